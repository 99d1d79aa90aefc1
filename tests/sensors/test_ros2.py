"""A robot's camera and odometry from ROS 2 (`sensors.ros2.Ros2Source`); bad input is refused
with a diagnostic naming what was wrong, never delivered: wrong encodings, a camera_info
that disagrees with sensor.yaml, odometry stamped in the future or out of order, odometry
in other frames."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest

from localizer.camera import T_body_camera_upward
from localizer.events import FrameObserved, OdometryMeasured
from localizer.robot import RobotGeometry
from ros2.camera_info import camera_info_of
from ros2.messages import header, new
from ros2.settings import Ros2Settings
from ros2.transport import Ros2Participant
from sensors.event_buffer import EventBuffer
from sensors.ros2 import Ros2Source, wall_minus_mono_ns
from tests.ros2.dds import CAMERA, image, odometry, participant

SETTINGS = Ros2Settings(namespace="r1")


@pytest.fixture(scope="module")
def node() -> Iterator[Ros2Participant]:
    yield from participant()


@pytest.fixture
def source(node: Ros2Participant) -> Ros2Source:
    src = Ros2Source("r1", node, SETTINGS, RobotGeometry(0.4, 1.0), camera=CAMERA)
    src.start(EventBuffer())
    return src


def now_ros() -> int:
    return time.time_ns()


def taken(source: Ros2Source) -> list[object]:
    """What the source delivered so far (its sink is an EventBuffer)."""
    buffer = source._sink
    assert isinstance(buffer, EventBuffer)
    return list(buffer.take_due(time.monotonic_ns()))


def test_a_mono8_frame_becomes_an_event_at_its_exposure(source: Ros2Source) -> None:
    t = now_ros() - 5_000_000
    data = bytes(range(256)) * 12
    source.on_image(image(t, data=data))
    (event,) = taken(source)
    assert isinstance(event, FrameObserved)
    np.testing.assert_array_equal(event.image.ravel(), np.frombuffer(data, np.uint8))
    assert abs(event.t_ns + wall_minus_mono_ns() - t) < 1_000_000
    assert source.ros_stamp(event.t_ns) == t  # the frame's own stamp, for what is published


@pytest.mark.parametrize(
    ("encoding", "step", "size", "says"),
    [
        ("yuv422", 128, 64 * 48 * 2, "not supported"),
        ("rgb8", 64, 64 * 48, "encoding does not match the data"),
        ("mono16", 128, 64 * 48, "encoding does not match the data"),
        ("mono8", 64, 64 * 40, "encoding does not match the data"),
    ],
)
def test_a_frame_that_is_not_what_it_says_is_refused(
    source: Ros2Source, encoding: str, step: int, size: int, says: str
) -> None:
    source.on_image(image(now_ros(), encoding, bytes(size), step))
    assert taken(source) == []
    problem = source.health.problem("image")
    assert problem is not None and problem.level == "error" and says in problem.message
    assert "/r1/image_raw" in problem.message


def test_encodings_a_camera_driver_publishes(source: Ros2Source) -> None:
    gray = np.arange(64 * 48, dtype=np.uint16).reshape(48, 64) % 251
    rgb = np.repeat(gray[:, :, None], 3, axis=2).astype(np.uint8)
    wide = (gray.astype(np.uint16) << 8).astype("<u2")
    t = now_ros() - 50_000_000
    source.on_image(image(t, "rgb8", rgb.tobytes(), 192))
    source.on_image(image(t + 1000, "mono16", wide.tobytes(), 128))
    source.on_image(image(t + 2000, "bayer_rggb8", gray.astype(np.uint8).tobytes(), 64))
    events = taken(source)
    assert [type(e) for e in events] == [FrameObserved] * 3
    for e in events[:2]:
        assert isinstance(e, FrameObserved)
        np.testing.assert_array_equal(e.image, gray.astype(np.uint8))


def test_a_camera_info_that_disagrees_with_sensor_yaml_stops_the_frames(
    source: Ros2Source,
) -> None:
    good = camera_info_of(CAMERA, now_ros(), "r1/camera")
    source.on_camera_info(good)
    assert source.health.problem("camera_info") is None
    bad = camera_info_of(CAMERA, now_ros(), "r1/camera")
    bad.k = [44.0, 0.0, 32.0, 0.0, 40.0, 24.0, 0.0, 0.0, 1.0]
    source.on_camera_info(bad)
    source.on_image(image(now_ros()))
    assert taken(source) == []
    problem = source.health.problem("camera_info")
    assert problem is not None and problem.level == "error"
    assert "fx 44.00 vs 40.00 px" in problem.message and "frames refused" in problem.message
    source.on_camera_info(good)  # the driver fixed: frames flow again
    source.on_image(image(now_ros()))
    assert [type(e) for e in taken(source)] == [FrameObserved]


def test_odometry_gives_wheel_speeds_from_its_twist(source: Ros2Source) -> None:
    source.on_odometry(odometry(now_ros() - 1_000_000, v=0.5, w=0.2))
    (e,) = taken(source)
    assert isinstance(e, OdometryMeasured)
    assert e.v_left == pytest.approx(0.5 - 0.04) and e.v_right == pytest.approx(0.5 + 0.04)


def test_odometry_from_the_future_or_out_of_order_is_refused(source: Ros2Source) -> None:
    source.on_odometry(odometry(now_ros() + 2_000_000_000))
    p = source.health.problem("odom")
    assert p is not None and p.level == "error" and "s in the future" in p.message
    t = now_ros() - 20_000_000
    source.on_odometry(odometry(t))
    source.on_odometry(odometry(t - 5_000_000))  # older than the one before
    source.on_odometry(odometry(t))  # the same stamp again
    assert len(taken(source)) == 1
    p = source.health.problem("odom")
    assert p is not None and "out of order" in p.message and p.count >= 2


def test_wheel_speeds_from_joint_states(node: Ros2Participant) -> None:
    settings = Ros2Settings(
        namespace="r1", wheel_joints="wheel_left_joint,wheel_right_joint", wheel_radius_m=0.05
    )
    src = Ros2Source("r1", node, settings, RobotGeometry(0.4, 1.0), camera=CAMERA)
    src.start(EventBuffer())

    def joints(t_ns: int, names: list[str], vel: list[float]) -> object:
        return new(
            "sensor_msgs/msg/JointState", header=header(t_ns, ""), name=names, velocity=vel,
            position=[0.0] * len(names),
        )  # fmt: skip

    t = now_ros() - 10_000_000
    src.on_joint_states(joints(t, ["caster", "wheel_right_joint", "wheel_left_joint"], [9, 12, 10]))
    src.on_joint_states(joints(t + 1, ["arm_joint"], [1.0]))  # other joints: not ours
    src.on_joint_states(joints(t + 2, ["wheel_left_joint", "wheel_right_joint"], [1.0]))
    (e,) = taken(src)
    assert isinstance(e, OdometryMeasured)
    assert (e.v_left, e.v_right) == pytest.approx((0.5, 0.6))
    p = src.health.problem("odom")
    assert p is not None and "1 velocities for 2 joints" in p.message
    with pytest.raises(ValueError, match="wheel_radius_m"):
        Ros2Settings(wheel_joints="a,b")


def test_odometry_in_other_frames_is_refused(source: Ros2Source) -> None:
    source.on_odometry(odometry(now_ros(), frame="odom"))
    assert taken(source) == []
    p = source.health.problem("odom")
    assert p is not None and "'odom' -> 'r1/base_link', expected 'r1/odom'" in p.message


def test_without_sensor_yaml_the_lens_comes_from_camera_info(node: Ros2Participant) -> None:
    src = Ros2Source("r2", node, SETTINGS, RobotGeometry(0.4, 1.0), camera=None)
    src.start(EventBuffer())
    with pytest.raises(TimeoutError, match="/r1/camera_info"):
        src.wait_for_camera(0.01)
    src.on_image(image(now_ros()))
    assert taken(src) == []
    src.on_camera_info(camera_info_of(CAMERA, now_ros(), "r1/camera"))
    cam = src.wait_for_camera(0.01)
    assert (cam.fu, cam.cu, cam.width) == (40.0, 32.0, 64)
    np.testing.assert_allclose(cam.T_body_camera, T_body_camera_upward(height=0.3))
