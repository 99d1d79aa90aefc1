"""`irloc replay --start-pose`, a recording's `start_pose.yaml`, `--config` and the settings
record: a recording whose LEDs never blink (every LED lit from the start), with and without
odometry."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from localizer.events import LedsChanged
from localizer.geometry import T_world_body_from_pose
from localizer.robot import RobotGeometry
from recording.replay_cli import main
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera
from sim.render import render_frame
from tests.recording.test_replay import LANDMARKS, _pose


def _write_lit(root: Path, *, odometry: bool, duration_s: float = 1.5) -> Path:
    """Every LED lit from the first frame (no identification sweep): the drive of
    `test_replay`, with or without odometry."""
    cam = wide_angle_camera("pinhole")
    rng = np.random.default_rng(3)
    wheel_base = 0.36
    records: list[dict[str, Any]] = [dict(r) for r in LANDMARKS]  # type: ignore[call-overload]
    pos = np.array([(r["x"], r["y"], r["z"]) for r in records])
    with RecordingWriter(root, cam, RobotGeometry(wheel_base, 1.0), records) as w:
        w.add_leds(LedsChanged(0, all_lit=True))
        if odometry:
            for k in range(int(duration_s * 100) + 1):
                t = k / 100
                v = 0.3 if t > 0.5 else 0.0
                w.add_odometry(int(t * 1e9), v * (1 - wheel_base / 0.6), v * (1 + wheel_base / 0.6))
        for k in range(int(duration_s * 30)):
            t_ns = 10_000_000 + k * 33_333_333
            pose = _pose(t_ns * 1e-9)
            img = render_frame(cam, T_world_body_from_pose(*pose), pos, np.ones(3), rng=rng)
            w.add_frame(t_ns, img)
            w.add_groundtruth(t_ns, *pose)
    return root


@pytest.fixture(scope="module")
def lit_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write_lit(tmp_path_factory.mktemp("lit"), odometry=True)


@pytest.fixture(scope="module")
def lit_no_odometry(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write_lit(tmp_path_factory.mktemp("lit_noodo"), odometry=False)


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def _errors_cm(rows: list[dict[str, str]]) -> list[float]:
    out = []
    for r in rows:
        if r["mode"] == "landmark":
            x, y, _ = _pose(int(r["timestamp_ns"]) * 1e-9)
            out.append(100 * math.hypot(float(r["x"]) - x, float(r["y"]) - y))
    return out


def test_without_a_start_pose_a_lit_ceiling_gives_no_pose(
    lit_recording: Path, tmp_path: Path
) -> None:
    out = tmp_path / "poses.csv"
    assert main([str(lit_recording), "--out", str(out), "--quiet"]) == 0
    rows = _rows(out)
    assert {r["mode"] for r in rows} == {"identifying"}
    assert all(r["x"] == "" for r in rows)


@pytest.mark.parametrize("which", ["lit_recording", "lit_no_odometry"])
def test_start_pose_on_the_command_line_is_honoured(
    which: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    rec: Path = request.getfixturevalue(which)
    out = tmp_path / "poses.csv"
    # 25 cm and 6 deg off the true start (0.6, 0.3, 0), searched within 0.5 m
    assert main([str(rec), "--out", str(out), "--quiet", "--start-pose", "0.8,0.15,0.1,0.5"]) == 0
    rows = _rows(out)
    assert rows[0]["x"] != ""  # a pose from the first frame on
    landmark = [r for r in rows if r["mode"] == "landmark"]
    assert len(landmark) >= 0.9 * len(rows)
    errors = _errors_cm(rows)
    assert max(errors) < 2.0
    record = yaml.safe_load((tmp_path / "poses.settings.yaml").read_text())
    assert record["start_pose"] == {"x": 0.8, "y": 0.15, "theta": 0.1, "radius_m": 0.5}
    assert record["start_pose_source"] == "command line"
    assert record["localizer"]["motion"]["accel_sigma_m_s2"] == 1.0


def test_a_recordings_start_pose_is_used_unless_told_not_to(
    lit_recording: Path, tmp_path: Path
) -> None:
    rec = tmp_path / "rec"
    rec.mkdir()
    for item in lit_recording.iterdir():
        (rec / item.name).symlink_to(item)
    (rec / "start_pose.yaml").write_text("x: 0.7\ny: 0.2\ntheta: -0.05\nradius_m: 0.4\n")
    out = tmp_path / "poses.csv"
    assert main([str(rec), "--out", str(out), "--quiet"]) == 0
    assert sum(r["mode"] == "landmark" for r in _rows(out)) >= 0.9 * len(_rows(out))
    assert yaml.safe_load((tmp_path / "poses.settings.yaml").read_text())["start_pose_source"] == (
        "recording"
    )
    assert main([str(rec), "--out", str(out), "--quiet", "--no-start-pose"]) == 0
    assert {r["mode"] for r in _rows(out)} == {"identifying"}


def test_config_file_is_applied_and_a_bad_key_is_named(
    lit_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = tmp_path / "good.yaml"
    good.write_text("detection: {max_area_px: 900}\nfusion: {initial_sigma_m: 0.3}\n")
    out = tmp_path / "poses.csv"
    assert main([str(lit_recording), "--out", str(out), "--quiet", "--config", str(good),
                 "--start-pose", "0.7,0.25,0"]) == 0  # fmt: skip
    record = yaml.safe_load((tmp_path / "poses.settings.yaml").read_text())
    assert record["localizer"]["detection"]["max_area_px"] == 900
    assert record["config_file"] == str(good)
    # the record is itself a settings file: the same run again
    again = tmp_path / "again.csv"
    record = str(tmp_path / "poses.settings.yaml")
    argv = [str(lit_recording), "--out", str(again), "--quiet", "--config", record]
    assert main([*argv, "--start-pose", "0.7,0.25,0"]) == 0
    assert again.read_text() == out.read_text()

    bad = tmp_path / "bad.yaml"
    bad.write_text("detection: {max_aera_px: 900}\n")
    assert main([str(lit_recording), "--out", str(out), "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "detection.max_aera_px" in err and "unknown setting" in err
    bad.write_text("tracking: {sigma_gate: fast}\n")
    assert main([str(lit_recording), "--out", str(out), "--config", str(bad)]) == 2
    assert "tracking.sigma_gate: expected a number, got 'fast'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "message"),
    [("1,2", "expected X,Y,THETA[,RADIUS]"), ("1,b,0", "Y must be a number"),
     ("1,2,0,-1", "radius_m must be a positive number")],
)  # fmt: skip
def test_bad_start_pose_is_a_clear_error(
    lit_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
    message: str,
) -> None:  # fmt: skip
    assert main([str(lit_recording), "--out", str(tmp_path / "p.csv"), "--start-pose", text]) == 2
    assert message in capsys.readouterr().err


def test_passive_lights_on_a_symmetric_bed_say_why_and_a_start_pose_decides(
    lit_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The paper's bed treated as passive lights (`passive: {mode: all}`): an equilateral
    triangle looks the same turned by 120 deg, so from a cold start no frame can decide."""
    settings = tmp_path / "passive.yaml"
    settings.write_text("passive: {mode: all}\n", encoding="utf-8")
    out = tmp_path / "poses.csv"
    assert main([str(lit_recording), "--out", str(out), "--config", str(settings),
                 "--no-truth"]) == 0  # fmt: skip
    assert {r["mode"] for r in _rows(out)} == {"identifying"}  # no guess
    err = capsys.readouterr().err
    assert "no pose yet, ambiguous: 3 distinct poses explain the 3 spots alike" in err
    started = tmp_path / "started.csv"
    argv = [str(lit_recording), "--out", str(started), "--quiet", "--config", str(settings)]
    assert main([*argv, "--start-pose", "0.65,0.25,0.1,0.3"]) == 0
    errs = _errors_cm(_rows(started))
    assert len(errs) >= 0.9 * len(_rows(started)) and max(errs) < 1.0
