"""start_pose.yaml and imu0/ (EuRoC layout) in the recording contract: optional, read and
written, bad content named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from localizer.events import ImuMeasured, OdometryMeasured
from localizer.robot import RobotGeometry
from recording.reader import RecordingError, iter_timeline, read_recording
from recording.start_pose import StartPose, parse_start_pose, start_pose_from_dict
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera

LANDMARKS = [{"id": 1, "x": 0.0, "y": 0.0, "z": 2.5}, {"id": 2, "x": 1.0, "y": 0.0, "z": 2.5}]


def _writer(root: Path) -> RecordingWriter:
    return RecordingWriter(root, wide_angle_camera("pinhole"), RobotGeometry(0.36, 1.0), LANDMARKS)


def test_start_pose_and_imu_round_trip(tmp_path: Path) -> None:
    with _writer(tmp_path) as w:
        w.set_start_pose(1.5, -0.25, math.pi / 2, 0.3)
        w.add_odometry(10, 0.1, 0.1)
        w.add_imu(10, (0.0, 0.01, 0.5), (0.1, 0.0, 9.81))
        w.add_imu(20, (0.0, 0.0, -0.25), (0.0, 0.2, 9.8))
    rec = read_recording(tmp_path)
    assert rec.start_pose == StartPose(1.5, -0.25, math.pi / 2, 0.3)
    np.testing.assert_array_equal(rec.imu_t_ns, [10, 20])
    np.testing.assert_allclose(rec.imu[0], [0.0, 0.01, 0.5, 0.1, 0.0, 9.81])
    items = list(iter_timeline(rec))
    assert isinstance(items[0], OdometryMeasured)  # odometry first at equal times
    assert items[1] == ImuMeasured(10, (0.0, 0.01, 0.5), (0.1, 0.0, 9.81))


def test_without_the_optional_files(tmp_path: Path) -> None:
    with _writer(tmp_path):
        pass
    rec = read_recording(tmp_path)
    assert rec.start_pose is None
    assert rec.imu.shape == (0, 6) and rec.imu_t_ns.shape == (0,)


def test_imu_axes_are_rotated_into_the_body_frame(tmp_path: Path) -> None:
    with _writer(tmp_path):
        pass
    (tmp_path / "imu0").mkdir()
    # an IMU mounted yawed +90 deg: its x is the body's y
    T = [0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    (tmp_path / "imu0/sensor.yaml").write_text(f"T_BS: {{rows: 4, cols: 4, data: {T}}}\n")
    (tmp_path / "imu0/data.csv").write_text("#t,wx,wy,wz,ax,ay,az\n5,0,0,0.3,1.0,0,9.81\n")
    rec = read_recording(tmp_path)
    np.testing.assert_allclose(rec.imu[0], [0, 0, 0.3, 0, 1.0, 9.81], atol=1e-12)


@pytest.mark.parametrize(
    ("file", "text", "message"),
    [
        ("start_pose.yaml", "x: 1\ny: 2\n", "missing key 'theta'"),
        ("start_pose.yaml", "x: 1\ny: 2\ntheta: 0\nradius: 1\n", "unknown key 'radius'"),
        ("start_pose.yaml", "x: a\ny: 2\ntheta: 0\n", "x must be a finite number"),
        ("start_pose.yaml", "x: 1\ny: 2\ntheta: 0\nradius_m: -1\n", "radius_m must be"),
        ("imu0/data.csv", "#h\n5,0,0,0.3,1.0,0\n", "expected 7 fields"),
        ("imu0/data.csv", "#h\n5,0,0,x,1.0,0,9\n", "w_z must be a number"),
    ],
)
def test_bad_content_names_the_file(tmp_path: Path, file: str, text: str, message: str) -> None:
    with _writer(tmp_path):
        pass
    (tmp_path / file).parent.mkdir(exist_ok=True)
    (tmp_path / file).write_text(text)
    with pytest.raises(RecordingError) as info:
        read_recording(tmp_path)
    assert info.value.file.endswith(file)
    assert message in str(info.value)


def test_parse_start_pose() -> None:
    assert parse_start_pose("1, 2.5, -0.5") == StartPose(1.0, 2.5, -0.5)
    assert parse_start_pose("1,2,3,0.4").radius_m == 0.4
    with pytest.raises(ValueError, match="THETA must be a number"):
        parse_start_pose("1,2,north")
    with pytest.raises(ValueError, match="timestamp_ns must be an integer"):
        start_pose_from_dict({"x": 0, "y": 0, "theta": 0, "timestamp_ns": 1.5})
