"""`irloc calibrate mounting` on a simulated recording: sweep, turn in place, straight."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from irloc.calibrate_cli import main
from localizer.camera import T_body_camera_upward, camera_from_sensor
from localizer.events import LedsChanged
from localizer.geometry import T_world_body_from_pose
from localizer.robot import RobotGeometry
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera
from sim.render import render_frame
from tests.calibration.test_mounting import WHEEL_BASE, _drive, _landmarks

T_TRUE = T_body_camera_upward(yaw=math.pi / 2, offset_xy=(0.07, 0.07), height=0.3)


def _write_recording(root: Path, *, sweep: bool = True) -> None:
    rng = np.random.default_rng(8)
    landmarks = _landmarks(rng)
    records = [
        {"id": int(i), "x": float(p[0]), "y": float(p[1]), "z": float(p[2])}
        for i, p in zip(landmarks.ids, landmarks.positions, strict=True)
    ]
    true_camera = wide_angle_camera("fisheye", T_body_camera=T_TRUE)
    writer = RecordingWriter(root, wide_angle_camera("fisheye"), RobotGeometry(WHEEL_BASE), records)
    odo, pose, t_end = _drive(turn_rad=math.pi, straight_m=1.0)
    t0 = 0.1 * len(landmarks) + 0.5 if sweep else 0.0  # the drive starts after the sweep
    for k in range(len(landmarks)) if sweep else ():
        t = 0.1 * k
        writer.add_leds(LedsChanged(round(t * 1e9), lit=frozenset({int(landmarks.ids[k])})))
        lit = np.zeros(len(landmarks))
        lit[k] = 1.0
        T_wb = T_world_body_from_pose(*pose(0.0))
        frame = render_frame(true_camera, T_wb, landmarks.positions, lit, rng=rng)
        writer.add_frame(round((t + 0.05) * 1e9), frame)
    writer.add_leds(LedsChanged(round(max(t0 - 0.3, 0.0) * 1e9), all_lit=True))
    for t in np.arange(0.0, t0, 0.02):
        writer.add_odometry(round(t * 1e9), 0.0, 0.0)
    for t_ns, vl, vr in odo:
        writer.add_odometry(t_ns + round(t0 * 1e9), vl, vr)
    for t in np.arange(0.0, t_end, 0.2):  # 5 Hz
        T_wb = T_world_body_from_pose(*pose(t))
        frame = render_frame(
            true_camera, T_wb, landmarks.positions, np.ones(len(landmarks)), rng=rng
        )
        writer.add_frame(round((t + t0) * 1e9), frame)
    writer.close()


@pytest.mark.slow
def test_writes_the_measured_mounting(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _write_recording(tmp_path / "rec")
    out, report = tmp_path / "sensor.yaml", tmp_path / "mounting.json"
    code = main(["mounting", str(tmp_path / "rec"), "--out", str(out), "--report", str(report)])
    assert code == 0, capsys.readouterr().err
    cam = camera_from_sensor(yaml.safe_load(out.read_text()))
    np.testing.assert_allclose(cam.T_body_camera[:2, 3], [0.07, 0.07], atol=0.005)
    np.testing.assert_allclose(cam.T_body_camera[:3, :3], T_TRUE[:3, :3], atol=0.004)
    np.testing.assert_allclose(cam.fu, wide_angle_camera("fisheye").fu)  # the lens is kept
    data = json.loads(report.read_text())
    assert data["yaw_deg"] == pytest.approx(90.0, abs=0.2)
    yaw = re.search(r"yaw: (\S+) deg", capsys.readouterr().out)
    assert yaw is not None and float(yaw.group(1)) == pytest.approx(90.0, abs=0.2)


def test_recording_without_the_sweep_fails_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _write_recording(tmp_path / "rec", sweep=False)
    out = tmp_path / "sensor.yaml"
    assert main(["mounting", str(tmp_path / "rec"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("irloc calibrate mounting: error: mounting: no usable frame")
    assert not out.exists()
    assert main(["mounting", str(tmp_path / "missing"), "--out", str(out)]) == 1
    assert "missing" in capsys.readouterr().err and not out.exists()
