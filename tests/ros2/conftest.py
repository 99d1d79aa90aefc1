"""DDS tests: a domain id of their own per test run (ROS_DOMAIN_ID) and loopback only
(ROS_LOCALHOST_ONLY=1: the machine has no network)."""

from __future__ import annotations

import pytest

from tests.ros2.dds import DOMAIN_ID


@pytest.fixture(autouse=True)
def ros_domain(monkeypatch: pytest.MonkeyPatch) -> int:
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_ID))
    monkeypatch.setenv("ROS_LOCALHOST_ONLY", "1")
    return DOMAIN_ID
