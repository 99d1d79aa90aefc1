"""`irloc replay`: one row per frame, accuracy on a short simulated recording, bad input."""

from __future__ import annotations

import csv
import io
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from localizer.events import LedsChanged
from localizer.geometry import T_world_body_from_pose
from localizer.robot import RobotGeometry
from recording.replay_cli import HEADER, main, replay
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera
from sim.render import render_frame

LANDMARKS = [
    {"id": 1, "x": 0.0, "y": 0.0, "z": 2.5},
    {"id": 2, "x": 1.2, "y": 0.0, "z": 2.5},
    {"id": 3, "x": 0.6, "y": 1.0392, "z": 2.45, "radio": "0013A20040A1B2C3"},
]


def _pose(t: float) -> tuple[float, float, float]:
    """Parked for 0.5 s, then a circle of radius 0.3 m at 0.3 m/s."""
    s = max(t - 0.5, 0.0)
    return 0.6 + 0.3 * math.sin(s), 0.3 + 0.3 * (1 - math.cos(s)), s


def write_recording(root: Path, *, duration_s: float = 2.0, seed: int = 0) -> Path:
    """A short recording of the start-up sweep (none, 1, 2, all) and a drive."""
    cam = wide_angle_camera("pinhole")
    rng = np.random.default_rng(seed)
    wheel_base = 0.36
    pos = {r["id"]: (r["x"], r["y"], r["z"]) for r in LANDMARKS}
    sweep = [(0, frozenset(), False), (60, frozenset({1}), False), (130, frozenset({2}), False),
             (200, frozenset(), True)]  # fmt: skip
    with RecordingWriter(root, cam, RobotGeometry(wheel_base, 1.0), LANDMARKS) as w:
        for t_ms, lit, all_lit in sweep:
            w.add_leds(LedsChanged(t_ms * 1_000_000, lit, all_lit))
        for k in range(int(duration_s * 100) + 1):
            t = k / 100
            v = 0.3 if t > 0.5 else 0.0
            w.add_odometry(int(t * 1e9), v * (1 - wheel_base / 0.6), v * (1 + wheel_base / 0.6))
        for k in range(int(duration_s * 30)):
            t_ns = 10_000_000 + k * 33_333_333
            state = [s for s in sweep if s[0] * 1_000_000 <= t_ns][-1]
            ids = [i for i in pos if state[2] or i in state[1]]
            sources = np.array([pos[i] for i in ids]).reshape(-1, 3)
            pose = _pose(t_ns * 1e-9)
            img = render_frame(
                cam, T_world_body_from_pose(*pose), sources, np.ones(len(ids)), rng=rng
            )
            w.add_frame(t_ns, img)
            w.add_groundtruth(t_ns, *pose)
    return root


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_recording(tmp_path_factory.mktemp("rec") / "rec")


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def test_replay_writes_one_accurate_row_per_frame(recording: Path, tmp_path: Path) -> None:
    out = tmp_path / "poses.csv"
    assert main([str(recording), "--out", str(out), "--quiet"]) == 0
    assert out.read_text().splitlines()[0] == HEADER
    rows = _rows(out)
    listed = (recording / "cam0" / "data.csv").read_text().splitlines()[1:]
    assert [r["timestamp_ns"] for r in rows] == [line.split(",")[0] for line in listed]
    assert rows[0]["x"] == "" and rows[0]["mode"] == "identifying"
    posed = [r for r in rows if r["x"]]
    assert len(posed) > 0.85 * len(rows)
    first = int(posed[0]["timestamp_ns"])
    assert first < 0.5e9
    err = [
        math.hypot(float(r["x"]) - _pose(int(r["timestamp_ns"]) * 1e-9)[0],
                   float(r["y"]) - _pose(int(r["timestamp_ns"]) * 1e-9)[1])
        for r in posed
    ]  # fmt: skip
    assert max(err) < 0.01
    assert {r["mode"] for r in posed} <= {"landmark", "dead_reckoning"}
    assert posed[-1]["landmarks"] == "1 2 3"
    assert float(posed[-1]["cov_xx"]) > 0
    # quality, the 95 % radius and the reason (docs/quality.md)
    assert rows[0]["reason"] in ("identifying", "waiting_for_radio")
    assert rows[0]["quality"] == "0.000" and rows[0]["deviation_m"] == ""
    fixed = [r for r in posed if r["mode"] == "landmark"]
    assert fixed and all(r["reason"] == "" for r in fixed)
    assert all(0.0245 < float(r["deviation_m"]) < 0.04 for r in fixed[5:])
    assert all(0.9 < float(r["quality"]) <= 1.0 for r in fixed[5:])


def test_unreadable_frames_are_skipped_counted_and_still_get_a_row(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    listed = (rec / "cam0" / "data.csv").read_text().splitlines()[1:]
    frames = [rec / "cam0" / "data" / line.split(",")[1] for line in listed]
    frames[30].unlink()
    frames[31].write_bytes(b"not a png")
    out = tmp_path / "poses.csv"
    assert main([str(rec), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert err.count("warning:") == 2
    assert "2 unreadable frames skipped" in err
    rows = _rows(out)
    assert len(rows) == len(frames)
    assert rows[30]["x"] != "" and rows[30]["mode"] == "dead_reckoning"
    assert rows[30]["reason"] == rows[31]["reason"] == "frames_dropped"


def test_a_recording_whose_every_frame_is_unreadable_is_a_failure(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    for png in (rec / "cam0" / "data").iterdir():
        png.write_bytes(b"not a png")
    assert main([str(rec), "--out", str(tmp_path / "poses.csv"), "--quiet"]) == 1
    assert "every frame" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("file", "text", "where"),
    [
        ("odom0/data.csv", "#timestamp [ns],v_left [m/s],v_right [m/s]\n100,abc,0.1\n", ":2:"),
        ("cam0/data.csv", "#timestamp [ns],filename\nxyz,1.png\n", ":2:"),
        ("leds.csv", "#timestamp [ns],on\n0,none\n5,99\n", ":3:"),
        ("map.json", "{not json", "map.json"),
    ],
)
def test_malformed_file_gives_one_line_and_non_zero_status(
    recording: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    file: str,
    text: str,
    where: str,
) -> None:
    import shutil

    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    (rec / file).write_text(text)
    out = tmp_path / "poses.csv"
    assert main([str(rec), "--out", str(out), "--quiet"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("irloc replay: ") and file.split("/")[-1] in err and where in err
    assert "Traceback" not in err
    assert not out.exists()


def test_missing_recording_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(tmp_path / "nope"), "--out", str(tmp_path / "p.csv")]) == 1
    assert "not a recording folder" in capsys.readouterr().err


@pytest.mark.slow
def test_replay_of_a_simulated_scenario_end_to_end(tmp_path: Path) -> None:
    from irloc.simulate_cli import main as simulate
    from recording.reader import read_groundtruth

    rec = tmp_path / "hostile"
    assert simulate(["hostile", str(rec), "--duration", "6", "--quiet"]) == 0
    out = tmp_path / "poses.csv"
    assert main([str(rec), "--out", str(out), "--quiet"]) == 0
    t_gt, gt = read_groundtruth(rec)
    rows = [r for r in _rows(out) if r["x"]]
    assert int(rows[0]["timestamp_ns"]) < 2e9  # first fix within 2 s
    t = np.array([int(r["timestamp_ns"]) for r in rows])
    err = np.hypot(
        np.array([float(r["x"]) for r in rows]) - np.interp(t, t_gt, gt[:, 0]),
        np.array([float(r["y"]) for r in rows]) - np.interp(t, t_gt, gt[:, 1]),
    )
    assert np.percentile(err, 95) < 0.10


def test_decoding_threads_do_not_change_the_output(recording: Path) -> None:
    switch = sys.getswitchinterval()
    outs = []
    for threads in (1, 3):
        buf = io.StringIO()
        assert replay(recording, buf, threads=threads) == (60, 0)
        outs.append(buf.getvalue())
    assert outs[0] == outs[1]
    assert sys.getswitchinterval() == switch  # restored after the replay
