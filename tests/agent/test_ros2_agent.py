"""The agent's ROS 2 sensor source: inputs in time order, a late one dropped (not fed out
of order) with a diagnostic, /initialpose as a relocalization request."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from agent.ros2_agent import Ros2SensorSource
from localizer.events import OdometryMeasured, RelocalizeRequested
from localizer.robot import RobotGeometry
from ros2.initialpose import InitialPoseListener
from ros2.messages import header, new, pose_msg
from ros2.settings import Ros2Settings
from ros2.transport import Ros2Participant
from sensors.ros2 import Ros2Source
from tests.ros2.dds import CAMERA, participant

SETTINGS = Ros2Settings(namespace="r1")


@pytest.fixture(scope="module")
def node() -> Iterator[Ros2Participant]:
    yield from participant()


@pytest.fixture
def source(node: Ros2Participant) -> Ros2SensorSource:
    src = Ros2SensorSource(Ros2Source("r1", node, SETTINGS, RobotGeometry(0.4, 1.0), camera=CAMERA))
    src.initialpose = InitialPoseListener(node, SETTINGS, src.health, src.relocalize)
    src.start()
    return src


def odometry(t_ns: int) -> object:
    return new(
        "nav_msgs/msg/Odometry", header=header(t_ns, "r1/odom"), child_frame_id="r1/base_link"
    )


def test_inputs_come_in_time_order_and_a_late_one_is_dropped(source: Ros2SensorSource) -> None:
    now = time.time_ns()
    source.inputs.on_odometry(odometry(now - 30_000_000))
    source.inputs.on_odometry(odometry(now - 20_000_000))
    due = source.step(time.monotonic_ns())
    assert [type(e) for e in due] == [OdometryMeasured] * 2
    assert due[0].t_ns < due[1].t_ns
    source.inputs.on_odometry(odometry(now - 10_000_000))  # newer, but the agent went past it
    assert source.step(time.monotonic_ns()) == []
    problem = source.health.problem("odom")
    assert problem is not None and problem.level == "warn" and "--hold" in problem.message
    assert source.late == 1


def test_initialpose_asks_to_relocalize_near_it(source: Ros2SensorSource) -> None:
    assert source.initialpose is not None
    msg = new(
        "geometry_msgs/msg/PoseWithCovarianceStamped", header=header(time.time_ns(), "map"),
        pose=new("geometry_msgs/msg/PoseWithCovariance", pose=pose_msg((1.0, 2.0, 0.5))),
    )  # fmt: skip
    source.initialpose.on_message(msg)
    t = time.monotonic_ns()
    (e,) = source.step(t)
    assert isinstance(e, RelocalizeRequested) and e.t_ns == t
    assert e.near == pytest.approx((1.0, 2.0, 0.5))
    msg.header.frame_id = "odom"
    source.initialpose.on_message(msg)
    assert source.step(time.monotonic_ns()) == []
    p = source.health.problem("initialpose")
    assert p is not None and "/r1/initialpose in frame 'odom', expected 'map'" in p.message
