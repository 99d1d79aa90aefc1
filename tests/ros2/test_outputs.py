"""What the agent publishes: the pose at the frame's stamp, map -> odom composed with the
robot's own odom -> base_link at that stamp, nothing while lost, a diagnostic when the
transform is missing, the pose's quality and reason in the diagnostics."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from localizer.events import NoPose, PoseEstimate
from ros2.health import Health
from ros2.messages import compose, covariance3, pose2_of, stamp_ns
from ros2.outputs import Ros2Outputs
from ros2.settings import Ros2Settings
from ros2.transforms import TransformHistory
from ros2.transport import Ros2Participant
from tests.ros2.dds import participant

S = Ros2Settings(namespace="r1", max_wait_transform_s=0.05)


class Inbox:
    def __init__(self) -> None:
        self.items: list[Any] = []
        self.cond = threading.Condition()

    def __call__(self, msg: Any) -> None:
        with self.cond:
            self.items.append(msg)
            self.cond.notify_all()

    def wait(self, n: int, timeout: float = 3.0) -> list[Any]:
        with self.cond:
            self.cond.wait_for(lambda: len(self.items) >= n, timeout)
            return list(self.items)


@pytest.fixture(scope="module")
def node() -> Iterator[Ros2Participant]:
    yield from participant()


def outputs(node: Ros2Participant, name: str) -> tuple[Ros2Outputs, TransformHistory, Inbox, Inbox]:
    s = Ros2Settings(namespace=name, max_wait_transform_s=0.05)
    out = Ros2Outputs(node, s, Health(name), lambda t: t, name=name)
    history = out.odom_base
    poses, tfs = Inbox(), Inbox()
    node.subscribe(s.topic(s.pose_topic), "geometry_msgs/msg/PoseWithCovarianceStamped", poses)
    node.subscribe("/tf", "tf2_msgs/msg/TFMessage", tfs)
    time.sleep(0.2)
    return out, history, poses, tfs


def estimate(t: int, pose: tuple[float, float, float], mode: str = "landmark") -> PoseEstimate:
    cov = np.diag([4e-6, 9e-6, 1e-5])
    return PoseEstimate(t, *pose, covariance=cov, mode=mode, landmark_ids=(1, 2))  # type: ignore[arg-type]


def test_map_to_odom_is_the_pose_composed_with_odom_to_base(node: Ros2Participant) -> None:
    out, history, poses, tfs = outputs(node, "a1")
    t = time.time_ns() - 30_000_000
    history.add(t - 10_000_000, (1.0, 0.0, 0.0))
    history.add(t + 10_000_000, (1.2, 0.2, 0.2))  # odom -> base_link at t: (1.1, 0.1, 0.1)
    T_map_base = (3.0, 4.0, 1.0)
    out.on_pose(estimate(t, T_map_base))
    (pose,) = poses.wait(1)
    assert stamp_ns(pose.header.stamp) == t and pose.header.frame_id == "map"
    assert pose2_of(pose.pose.pose) == pytest.approx(T_map_base)
    np.testing.assert_allclose(covariance3(pose.pose.covariance), np.diag([4e-6, 9e-6, 1e-5]))
    tf = next(x for m in tfs.wait(1) for x in m.transforms if x.child_frame_id == "a1/odom")
    assert tf.header.frame_id == "map"
    assert stamp_ns(tf.header.stamp) == t + round(S.transform_tolerance_s * 1e9)
    T_map_odom = pose2_of(tf.transform)
    assert compose(T_map_odom, (1.1, 0.1, 0.1)) == pytest.approx(T_map_base, abs=1e-9)


def test_a_missing_transform_gives_a_diagnostic_not_a_transform(node: Ros2Participant) -> None:
    out, history, poses, tfs = outputs(node, "a2")
    out.has_map = True
    t = time.time_ns() - 100_000_000
    history.add(t - 500_000_000, (0.0, 0.0, 0.0))
    history.add(t - 400_000_000, (0.0, 0.0, 0.0))  # the latest is 400 ms older than the frame
    out.on_pose(estimate(t, (1.0, 1.0, 0.0)))
    assert len(poses.wait(1)) == 1  # the pose itself is right: it goes out
    time.sleep(S.max_wait_transform_s + 0.02)
    out._flush_transforms()
    problem = out.health.problem("transform")
    assert problem is not None and problem.level == "error"
    assert "no transform a2/odom -> a2/base_link at the frame's stamp" in problem.message
    assert "400 ms older" in problem.message
    assert not [x for m in tfs.items for x in m.transforms if x.child_frame_id == "a2/odom"]
    level, message, _ = out.status()
    assert level == "error" and "a2/odom" in message


def test_a_transform_that_arrives_late_still_gives_map_to_odom(node: Ros2Participant) -> None:
    """A reader thread that stalled delivers the pose's frame and the robot's odom -> base_link
    late: the pose, already older than `max_wait_transform_s`, still waits that long for the
    transform, and gets it."""
    out, history, _, tfs = outputs(node, "a4")
    t = time.time_ns() - 600_000_000  # a frame from before the stall
    history.add(t - 10_000_000, (1.0, 0.0, 0.0))
    out.on_pose(estimate(t, (3.0, 4.0, 1.0)))
    history.add(t + 10_000_000, (1.2, 0.2, 0.2))  # the odometry after the frame, caught up
    out._flush_transforms()
    tf = next(x for m in tfs.wait(1) for x in m.transforms if x.child_frame_id == "a4/odom")
    assert compose(pose2_of(tf.transform), (1.1, 0.1, 0.1)) == pytest.approx((3.0, 4.0, 1.0))
    assert out.health.problem("transform") is None


def test_nothing_is_published_while_lost(node: Ros2Participant) -> None:
    out, history, poses, _ = outputs(node, "a3")
    t = time.time_ns()
    history.add(t - 10, (0.0, 0.0, 0.0))
    history.add(t + 10, (0.0, 0.0, 0.0))
    out.has_map = True
    out.on_pose(estimate(t, (1.0, 1.0, 0.0), mode="lost"))
    out.on_pose(NoPose(t + 1, "lost"))
    time.sleep(0.3)
    assert poses.items == []
    level, message, values = out.status()
    assert level == "warn" and "send /initialpose" in message and ("mode", "lost") in values
    assert out.poses == 0


def test_the_diagnostics_carry_the_quality_the_radius_and_the_reason(
    node: Ros2Participant,
) -> None:
    out, _, poses, _ = outputs(node, "a4")
    out.has_map = True
    t = time.time_ns()
    cov = np.diag([2.5e-3, 1.6e-3, 3e-4])  # the published covariance: what /irloc/pose sends
    est = PoseEstimate(t, 1.0, 2.0, 0.5, cov, "dead_reckoning", quality=0.42,
                       deviation_m=0.117, reason="one_landmark_only",
                       reason_text="only one landmark in view; a fix needs two")  # fmt: skip
    out.on_pose(est)
    (pose,) = poses.wait(1)
    np.testing.assert_allclose(covariance3(pose.pose.covariance), cov)
    level, message, values = out.status()
    assert level == "warn" and message == "only one landmark in view; a fix needs two"
    assert {
        ("quality", "0.420"),
        ("deviation_m", "0.1170"),
        ("reason", "one_landmark_only"),
    } <= set(values)
    out.on_pose(NoPose(t + 1, "lost", reason="kidnapped_suspected", reason_text="lost: moved?"))
    level, message, values = out.status()
    assert (
        message == "lost: moved? (send /initialpose)"
        and ("reason", "kidnapped_suspected") in values
    )
    assert ("quality", "0.000") in values and ("deviation_m", "") in values
