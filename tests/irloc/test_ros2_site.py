"""`irloc serve --ros2-site`: the site server publishes every robot's pose and the landmark
map on ROS 2 (the demo's robots, localized on the server)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from irloc.ros2_site import SitePublisher, SiteWithRos2
from live.settings import Settings
from ros2.messages import covariance3, pose2_of
from ros2.transport import QOS_LATCHED, Ros2Participant
from server.main import create_app
from tests.ros2.dds import participant
from tests.server.conftest import TestClient


@pytest.fixture(scope="module")
def node() -> Iterator[Ros2Participant]:
    yield from participant()


def test_every_robots_pose_and_the_map_on_ros2(
    tmp_path: Path, node: Ros2Participant, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tests.ros2.dds import DOMAIN_ID

    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_ID))
    monkeypatch.setenv("ROS_LOCALHOST_ONLY", "1")
    got: dict[str, list[Any]] = {"r1": [], "map": []}
    done = threading.Event()

    def on_pose(msg: Any) -> None:
        got["r1"].append(msg)
        if len(got["r1"]) >= 5 and got["map"]:
            done.set()

    node.subscribe("/irloc/robots/r1/pose", "geometry_msgs/msg/PoseWithCovarianceStamped", on_pose)
    node.subscribe(
        "/irloc/landmarks", "visualization_msgs/msg/MarkerArray", got["map"].append, QOS_LATCHED
    )
    settings = Settings(data_dir=tmp_path, viewer_enabled=False, battery_interval_s=None)
    app = create_app(settings, SiteWithRos2(None, SitePublisher()))
    with TestClient(app) as client:
        assert done.wait(60), f"poses {len(got['r1'])}, maps {len(got['map'])}"
        key = app.state.services.initial_admin_key
        auth = {"Authorization": f"Bearer {key}"}
        landmarks = client.get("/api/v1/landmarks", headers=auth).json()
    pose = got["r1"][-1]
    assert pose.header.frame_id == "map"
    assert abs(pose.header.stamp.sec - time.time()) < 10
    x, y, _ = pose2_of(pose.pose.pose)
    assert 0 <= x <= 16 and 0 <= y <= 8  # on the demo site
    assert covariance3(pose.pose.covariance)[0, 0] < 1e-3
    ids = {m.id for m in got["map"][-1].markers if m.ns == "irloc_landmarks" and m.action == 0}
    assert ids == {lm["id"] for lm in landmarks}
