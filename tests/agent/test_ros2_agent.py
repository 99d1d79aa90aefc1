"""The agent's ROS 2 sensor source: inputs in time order, a topic that stalls waited for
(its samples fed in order when they come, not dropped), one later than that dropped (not fed
out of order) with a diagnostic, /initialpose as a relocalization request."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from agent.ros2_agent import Ros2SensorSource
from localizer.events import FrameObserved, OdometryMeasured, RelocalizeRequested
from localizer.robot import RobotGeometry
from ros2.initialpose import InitialPoseListener
from ros2.messages import header, new, pose_msg
from ros2.settings import Ros2Settings
from ros2.transport import Ros2Participant
from sensors.ros2 import Ros2Source
from tests.ros2.dds import CAMERA, image, odometry, participant

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


MS = 1_000_000
WAIT_NS = 1_000 * MS  # AgentConfig.input_wait_s


def test_nothing_is_complete_before_the_first_input(source: Ros2SensorSource) -> None:
    """The agent's clock does not overtake a source starting up: the first samples, however
    late they come, are fed."""
    horizon = source.complete_until(time.monotonic_ns(), WAIT_NS)
    assert source.step(horizon) == []
    now = time.time_ns()
    source.inputs.on_odometry(odometry(now - 500 * MS))
    source.inputs.on_image(image(now - 490 * MS))
    source.inputs.on_odometry(odometry(now - 480 * MS))  # waits for the next image
    due = source.step(source.complete_until(time.monotonic_ns(), WAIT_NS))
    assert [type(e) for e in due] == [OdometryMeasured, FrameObserved] and source.late == 0


def test_a_stalled_topic_holds_the_agent_back_and_its_samples_come_in_order(
    source: Ros2SensorSource,
) -> None:
    """Odometry stalls for half a second (its reader thread starved) while images keep
    coming: the agent goes no further than the last odometry, then takes the stalled samples
    in time order among the images; none is dropped."""
    now = time.time_ns()
    source.inputs.on_odometry(odometry(now - 710 * MS))
    source.inputs.on_image(image(now - 700 * MS))
    source.inputs.on_odometry(odometry(now - 690 * MS))
    assert len(source.step(source.complete_until(time.monotonic_ns(), WAIT_NS))) == 2
    for k in range(1, 6):
        source.inputs.on_image(image(now - 695 * MS + k * 100 * MS))  # up to now - 195 ms
    due = source.step(source.complete_until(time.monotonic_ns(), WAIT_NS))
    assert [type(e) for e in due] == [OdometryMeasured]  # the images wait for their odometry
    for k in range(1, 51):
        source.inputs.on_odometry(odometry(now - 690 * MS + k * 10 * MS))  # the stall ends
    due = source.step(source.complete_until(time.monotonic_ns(), WAIT_NS))
    stamps = [e.t_ns for e in due]
    assert stamps == sorted(stamps) and source.late == 0
    assert [type(e) for e in due].count(FrameObserved) == 5
    assert [type(e) for e in due].count(OdometryMeasured) == 49  # the last one, after the
    # last image, waits for the next


def test_a_stream_silent_longer_than_the_wait_is_not_waited_for(
    source: Ros2SensorSource,
) -> None:
    now = time.time_ns()
    source.inputs.on_odometry(odometry(now - 3000 * MS))  # the wheels went quiet 3 s ago
    source.inputs.on_image(image(now - 100 * MS))
    t = time.monotonic_ns() - 150 * MS
    assert source.complete_until(t, WAIT_NS) == t
    assert [type(e) for e in source.step(t)] == [OdometryMeasured]


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
    assert (
        problem is not None and problem.level == "warn" and "silent for longer" in problem.message
    )
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
