"""Shared by the DDS tests: the domain of this test run (one per process: pytest-xdist
workers and runs side by side do not meet), a loopback-only participant (the machine has no
network) and a small calibrated camera."""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

from localizer.camera import CameraModel, T_body_camera_upward
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
