"""Shared by the DDS tests: the domain of this test run (one per process: pytest-xdist
workers and runs side by side do not meet), a loopback-only participant (the machine has no
network) and a small calibrated camera."""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

from localizer.camera import CameraModel, T_body_camera_upward
from ros2.messages import header, new, twist_msg
from ros2.transport import Ros2Participant

DOMAIN_ID = 100 + os.getpid() % 100
CAMERA = CameraModel(
    width=64, height=48, fu=40.0, fv=40.0, cu=32.0, cv=24.0,
    distortion_model="radial-tangential", distortion=np.zeros(5),
    T_body_camera=T_body_camera_upward(),
)  # fmt: skip
"""A 64 x 48 pinhole camera looking up (sensor.yaml of the tests)."""


def participant() -> Iterator[Ros2Participant]:
    """A participant on this run's domain, loopback only (a module fixture's body)."""
    node = Ros2Participant(DOMAIN_ID, localhost_only=True)
    yield node
    node.close()


def image(t_ns: int, encoding: str = "mono8", data: bytes | None = None, step: int = 64) -> object:
    """A 64 x 48 `sensor_msgs/Image` (CAMERA's size) stamped `t_ns` (ROS time)."""
    data = bytes(64 * 48) if data is None else data
    return new(
        "sensor_msgs/msg/Image", header=header(t_ns, "r1/camera"), height=48, width=64,
        encoding=encoding, step=step, data=data,
    )  # fmt: skip


def odometry(t_ns: int, v: float = 0.5, w: float = 0.2, frame: str = "r1/odom") -> object:
    """r1's `nav_msgs/Odometry` stamped `t_ns` (ROS time), moving at (v, w)."""
    return new(
        "nav_msgs/msg/Odometry", header=header(t_ns, frame), child_frame_id="r1/base_link",
        twist=twist_msg(v, w),
    )  # fmt: skip
