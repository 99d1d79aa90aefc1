from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from irloc.simulate_cli import main
from localizer.events import LedsChanged
from recording.reader import iter_timeline, read_groundtruth, read_recording


def test_simulate_writes_a_recording_that_reads_back(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    assert main(["paper_testbed", str(out), "--duration", "4", "--quiet"]) == 0
    rec = read_recording(out)
    assert len(rec.frames) == 121  # 30 Hz, t = 0 .. 4 s
    assert len(rec.odom_t_ns) == 400  # 100 Hz
    assert sorted(rec.landmark_map.ids.tolist()) == [1, 2, 3]
    assert all(r["radio"].startswith("0013A2004100000") for r in rec.landmark_records)
    assert rec.camera.distortion_model == "radial-tangential"
    # The identification sweep: dark, then one landmark at a time, then all.
    assert rec.leds[0] == LedsChanged(0)
    singles = rec.leds[1:-1]
    assert len(singles) == 2 and all(len(e.lit) == 1 and not e.all_lit for e in singles)
    assert rec.leds[-1].all_lit
    frames_per_single = [
        sum(1 for f in rec.frames if e.t_ns <= f.t_ns < n.t_ns)
        for e, n in zip(rec.leds[1:-1], rec.leds[2:], strict=True)
    ]
    assert all(n >= 3 for n in frames_per_single)
    t_gt, poses = read_groundtruth(out)
    np.testing.assert_array_equal(t_gt, [f.t_ns for f in rec.frames])
    np.testing.assert_allclose(poses[0], [0.6, 0.35, 0.0])
    # Parked during the sweep and the first wait (3 s), then the heading sweep starts.
    assert np.all(poses[t_gt < 3_000_000_000] == poses[0])
    assert abs(poses[-1, 2]) > 0.05
    items = list(iter_timeline(rec))
    assert len(items) == 121 + 400 + len(rec.leds)


def test_simulate_other_lens_and_robot_and_is_deterministic(tmp_path: Path) -> None:
    args = ["demo", "--duration", "1", "--lens", "pinhole", "--robot", "r2", "--quiet"]
    assert main([args[0], str(tmp_path / "a"), *args[1:]]) == 0
    assert main([args[0], str(tmp_path / "b"), *args[1:]]) == 0
    a, b = read_recording(tmp_path / "a"), read_recording(tmp_path / "b")
    assert a.camera.distortion_model == "radial-tangential"
    np.testing.assert_array_equal(a.odom_v, b.odom_v)
    assert read_groundtruth(tmp_path / "a")[1][0, 2] == pytest.approx(np.pi / 2)
    assert (tmp_path / "a" / "cam0" / "data" / "0.png").read_bytes() == (
        tmp_path / "b" / "cam0" / "data" / "0.png"
    ).read_bytes()


def test_simulate_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("robots: [{name: a, start: [0, 0]}]\nlandmarks: [{id: 1, x: 0, y: 0}]\n")
    assert main([str(bad), str(tmp_path / "o")]) == 2
    assert "bad.yaml: robots[0].start: expected [x, y, theta_deg]" in capsys.readouterr().err
    assert main(["nowhere", str(tmp_path / "o")]) == 2
    assert "no such scenario file" in capsys.readouterr().err
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    assert main(["demo", str(tmp_path / "full")]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["demo", str(tmp_path / "o"), "--robot", "zz", "--quiet"]) == 2
    assert "unknown robot 'zz'" in capsys.readouterr().err


def test_sweep_skips_the_dead_landmark_and_robot_waits_for_it(tmp_path: Path) -> None:
    out = tmp_path / "hostile"
    assert main(["hostile", str(out), "--duration", "1.5", "--quiet"]) == 0
    rec = read_recording(out)
    singles = [next(iter(e.lit)) for e in rec.leds if len(e.lit) == 1]
    assert 7 not in singles and len(singles) >= 2
    all_at = next(e.t_ns for e in rec.leds if e.all_lit)
    t_gt, poses = read_groundtruth(out)
    assert np.all(poses[t_gt <= all_at] == poses[0])  # parked until the sweep is done
    assert 30 <= len(rec.frames) <= 46  # 5 % of 46 frames dropped on average


def test_simulate_calibration_override_changes_the_true_lens_only(tmp_path: Path) -> None:
    for level in ("none", "poor"):
        args = ["paper_testbed", str(tmp_path / level), "--duration", "0.2", "--quiet"]
        assert main([*args, "--calibration", level]) == 0
    assert (tmp_path / "none" / "cam0" / "sensor.yaml").read_text() == (
        tmp_path / "poor" / "cam0" / "sensor.yaml"
    ).read_text()  # the localizer is handed the same nominal camera
    last = read_recording(tmp_path / "none").frames[-1].path.relative_to(tmp_path / "none")
    assert (tmp_path / "none" / last).read_bytes() != (tmp_path / "poor" / last).read_bytes()
