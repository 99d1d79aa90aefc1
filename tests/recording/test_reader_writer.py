from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from localizer.camera import T_body_camera_upward
from localizer.events import LedsChanged, OdometryMeasured
from localizer.robot import RobotGeometry
from recording.reader import (
    FrameEntry,
    RecordingError,
    iter_timeline,
    read_groundtruth,
    read_groundtruth_file,
    read_recording,
)
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera

RECORDS = [
    {"id": 11, "x": 0.6, "y": 0.3, "z": 2.5, "radio": "0013A20041000001"},
    {"id": 12, "x": 1.8, "y": 0.3, "z": 2.48, "radio": "0013A20041000002"},
    {"id": 13, "x": 1.2, "y": 1.34, "z": 2.51},
]


def _write(root: Path, lens: str = "fisheye") -> np.ndarray:
    camera = wide_angle_camera(
        lens, T_body_camera=T_body_camera_upward(yaw=0.3, offset_xy=(0.1, 0.02))
    )  # type: ignore[arg-type]
    image = np.random.default_rng(1).integers(0, 256, (480, 640), dtype=np.uint8)
    with RecordingWriter(root, camera, RobotGeometry(0.36, 0.8), RECORDS) as w:
        w.add_leds(LedsChanged(0, frozenset({11})))
        w.add_odometry(0, 0.0, 0.0)
        w.add_odometry(10_000_000, 0.1, 0.12)
        w.add_frame(10_000_000, image)
        w.add_leds(LedsChanged(20_000_000, all_lit=True))
        w.add_odometry(20_000_000, 0.2, -0.1)
        w.add_frame(33_333_333, image)
        w.add_leds(LedsChanged(40_000_000))
        w.add_groundtruth(10_000_000, 1.0, 2.0, -3.0)
        w.add_groundtruth(33_333_333, 1.5, 2.5, 3.1)
    return image


@pytest.mark.parametrize("lens", ["pinhole", "fisheye"])
def test_round_trip(tmp_path: Path, lens: str) -> None:
    image = _write(tmp_path, lens)
    rec = read_recording(tmp_path)
    assert rec.landmark_records == RECORDS
    np.testing.assert_array_equal(rec.landmark_map.ids, [11, 12, 13])
    np.testing.assert_allclose(rec.landmark_map.position(12), [1.8, 0.3, 2.48])
    assert rec.robot == RobotGeometry(0.36, 0.8)
    expected_cam = wide_angle_camera(
        lens, T_body_camera=T_body_camera_upward(yaw=0.3, offset_xy=(0.1, 0.02))
    )  # type: ignore[arg-type]
    np.testing.assert_allclose(rec.camera.K, expected_cam.K)
    np.testing.assert_allclose(rec.camera.distortion, expected_cam.distortion)
    np.testing.assert_allclose(rec.camera.T_body_camera, expected_cam.T_body_camera)
    assert rec.camera.distortion_model == expected_cam.distortion_model
    assert [f.t_ns for f in rec.frames] == [10_000_000, 33_333_333]
    assert [f.line for f in rec.frames] == [2, 3]
    np.testing.assert_array_equal(cv2.imread(str(rec.frames[1].path), cv2.IMREAD_UNCHANGED), image)
    np.testing.assert_array_equal(rec.odom_t_ns, [0, 10_000_000, 20_000_000])
    np.testing.assert_allclose(rec.odom_v, [[0, 0], [0.1, 0.12], [0.2, -0.1]])
    assert rec.leds == [
        LedsChanged(0, frozenset({11})),
        LedsChanged(20_000_000, all_lit=True),
        LedsChanged(40_000_000),
    ]
    t, poses = read_groundtruth(tmp_path)
    np.testing.assert_array_equal(t, [10_000_000, 33_333_333])
    np.testing.assert_allclose(poses, [[1.0, 2.0, -3.0], [1.5, 2.5, 3.1]])


def test_timeline_orders_odometry_and_leds_before_frame_at_equal_time(tmp_path: Path) -> None:
    _write(tmp_path)
    items = list(iter_timeline(read_recording(tmp_path)))
    kinds = [type(i).__name__ for i in items]
    assert kinds == [
        "OdometryMeasured",
        "LedsChanged",
        "OdometryMeasured",
        "FrameEntry",
        "OdometryMeasured",
        "LedsChanged",
        "FrameEntry",
        "LedsChanged",
    ]
    assert items[2] == OdometryMeasured(10_000_000, 0.1, 0.12)
    assert isinstance(items[3], FrameEntry) and items[3].t_ns == 10_000_000
    times = [i.t_ns for i in items]
    assert times == sorted(times)


def test_extra_columns_files_and_optional_files_are_ignored(tmp_path: Path) -> None:
    _write(tmp_path)
    (tmp_path / "notes.txt").write_text("hello")
    (tmp_path / "odom0" / "data.csv").write_text(
        "#timestamp [ns],v_left [m/s],v_right [m/s],extra\n5,0.1,0.2,9\n\n6,0.3,0.4,1,2\n"
    )
    (tmp_path / "leds.csv").unlink()
    rec = read_recording(tmp_path)
    np.testing.assert_array_equal(rec.odom_t_ns, [5, 6])
    np.testing.assert_allclose(rec.odom_v, [[0.1, 0.2], [0.3, 0.4]])
    assert rec.leds == []


@pytest.mark.parametrize(
    ("file", "content", "line", "message"),
    [
        ("cam0/data.csv", "#timestamp [ns],filename\n1,1.png\nabc,2.png\n", 3, "integer ns"),
        ("cam0/data.csv", "#h\n5,5.png\n4,4.png\n", 3, "earlier than 5"),
        ("cam0/data.csv", "#h\n5\n", 2, "expected 2 fields"),
        ("odom0/data.csv", "#h\n1,0.1,0.2\n2,0.1,fast\n", 3, "v_right must be a number"),
        ("odom0/data.csv", "#h\n1,0.1,nan\n", 2, "v_right must be finite"),
        ("odom0/data.csv", "#h\n1,1e30,0.1\n", 2, "v_left 1e30 is beyond"),
        ("leds.csv", "#h\n1,all\n2,11 99\n", 3, "landmark 99 is not in the map"),
        ("leds.csv", "#h\n1,some\n", 2, "expected 'all', 'none' or landmark IDs"),
        ("map.json", '{"landmarks": [\n{"id": 1, "x": 0,\n}]}', 3, "invalid JSON"),
        ("robot.yaml", "wheel_base: [1,\n", 2, "invalid YAML"),
    ],
)
def test_malformed_file_names_file_and_line(
    tmp_path: Path, file: str, content: str, line: int, message: str
) -> None:
    _write(tmp_path)
    (tmp_path / file).write_text(content)
    with pytest.raises(RecordingError, match=message) as info:
        read_recording(tmp_path)
    assert info.value.file == str(tmp_path / file)
    assert info.value.line == line
    assert str(info.value).startswith(f"{tmp_path / file}:{line}: ")


@pytest.mark.parametrize(
    ("file", "content", "message"),
    [
        ("map.json", '{"landmarks": [{"id": 1, "x": 0, "y": 0}]}', "landmark 1: missing 'z'"),
        ("map.json", "[]", "'landmarks' list"),
        ("robot.yaml", "max_speed: 1\n", "missing field 'wheel_base'"),
        ("cam0/sensor.yaml", "camera_model: pinhole\n", "missing field 'intrinsics'"),
    ],
)
def test_malformed_content_names_file(
    tmp_path: Path, file: str, content: str, message: str
) -> None:
    _write(tmp_path)
    (tmp_path / file).write_text(content)
    with pytest.raises(RecordingError, match=message) as info:
        read_recording(tmp_path)
    assert str(info.value) == f"{tmp_path / file}: {info.value.what}"
    assert isinstance(info.value, ValueError)


def test_missing_required_file(tmp_path: Path) -> None:
    _write(tmp_path)
    (tmp_path / "cam0" / "sensor.yaml").unlink()
    with pytest.raises(RecordingError, match=r"sensor\.yaml: missing file"):
        read_recording(tmp_path)
    with pytest.raises(RecordingError, match="not a recording folder"):
        read_recording(tmp_path / "nope")


def test_writer_rejects_time_going_backwards_and_bad_images(tmp_path: Path) -> None:
    camera = wide_angle_camera("pinhole")
    with RecordingWriter(tmp_path, camera, RobotGeometry(0.3), RECORDS) as w:
        w.add_odometry(10, 0.0, 0.0)
        with pytest.raises(ValueError, match="timestamp 9"):
            w.add_odometry(9, 0.0, 0.0)
        with pytest.raises(ValueError, match="uint8"):
            w.add_frame(10, np.zeros((4, 4), dtype=np.float32))
        with pytest.raises(ValueError, match=r"\[99\] are not in the map"):
            w.add_leds(LedsChanged(10, frozenset({99})))


def test_a_landmark_being_switched_is_written_lit_so_dark_means_surely_dark(
    tmp_path: Path,
) -> None:
    camera = wide_angle_camera("pinhole")
    ids = [r["id"] for r in RECORDS]
    with RecordingWriter(tmp_path, camera, RobotGeometry(0.3), RECORDS) as w:
        # darkening ids[0]: requested at 10 (still lit or already dark), confirmed at 20
        w.add_leds(LedsChanged(10, frozenset(ids), changing=frozenset({ids[0]})))
        w.add_leds(LedsChanged(20, frozenset(ids[1:])))
        # lighting it again: requested at 30 (may be lit already: written lit), confirmed 40
        w.add_leds(LedsChanged(30, frozenset(ids[1:]), changing=frozenset({ids[0]})))
        w.add_leds(LedsChanged(40, all_lit=True))
    text = (tmp_path / "leds.csv").read_text().splitlines()
    assert text[1:] == ["10,all", f"20,{' '.join(map(str, sorted(ids[1:])))}", "30,all", "40,all"]


def test_an_absurd_ground_truth_is_refused_naming_the_line(tmp_path: Path) -> None:
    gt = tmp_path / "gt.csv"
    gt.write_text("timestamp_ns,x,y,theta\n1,0.5,0.2,0.1\n2,1e308,0.2,0.1\n")
    with pytest.raises(RecordingError, match=r"x 1e308 is beyond") as info:
        read_groundtruth_file(gt)
    assert info.value.line == 3
