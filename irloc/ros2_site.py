"""`irloc serve --ros2-site`: the site server on ROS 2 for a ROS-based fleet side (an
Open-RMF fleet adapter reads robot poses this way): every robot's pose as
`/irloc/robots/<robot>/pose` (`geometry_msgs/PoseWithCovarianceStamped` in `map`, stamped
at the frame's time) and the landmark map as `/irloc/landmarks` (`MarkerArray`, transient
local, republished at each map change). Robots localized here and agents alike: it reads
the pose bus.

The server never imports ROS 2; this composes it in beside the viewer (`SiteWithRos2` is
what `create_app` is handed as its viewer app: the viewer's routes, and both started
with the site's services).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING, Any

from fastapi import APIRouter

from ros2.outputs import landmark_markers, pose_with_covariance
from ros2.transport import QOS_DEFAULT, QOS_LATCHED, Ros2Participant

if TYPE_CHECKING:
    from live.services import SiteServices
    from server.seams import Authenticate, ViewerApp

log = logging.getLogger(__name__)
MAP_FRAME = "map"


class SitePublisher:
    """Publishes the site's poses and map on ROS 2 while started."""

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._map_changed = threading.Event()
        self.sent = 0

    def start(self, services: SiteServices) -> None:
        self.node = Ros2Participant()
        self.services = services
        self._pubs: dict[str, Any] = {}
        self.markers = self.node.publisher(
            "/irloc/landmarks", "visualization_msgs/msg/MarkerArray", QOS_LATCHED
        )
        self._map_changed.set()
        services.map.add_listener(lambda *_: self._map_changed.set())
        self._poses = services.robots.subscribe_poses(maxsize=1000)
        self._thread = threading.Thread(target=self._run, name="ros2-site", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            self.node.close()

    def _publisher(self, robot: str) -> Any:
        pub = self._pubs.get(robot)
        if pub is None:
            topic = f"/irloc/robots/{robot}/pose"
            pub = self.node.publisher(
                topic, "geometry_msgs/msg/PoseWithCovarianceStamped", QOS_DEFAULT
            )
            self._pubs[robot] = pub
        return pub

    def _run(self) -> None:
        while not self._stop.wait(0.01):
            try:
                if self._map_changed.is_set():
                    self._map_changed.clear()
                    lmap = self.services.map.landmark_map()
                    self.markers.publish(landmark_markers(lmap, MAP_FRAME, time.time_ns()))
                while (p := self._poses.get_nowait()) is not None:
                    if p.x is None or p.y is None or p.theta is None or p.covariance is None:
                        continue
                    if p.mode not in ("landmark", "dead_reckoning"):
                        continue
                    stamp = time.time_ns() - (self.services.clock_ns() - p.t_ns)
                    msg = pose_with_covariance((p.x, p.y, p.theta), p.covariance, stamp, MAP_FRAME)
                    self._publisher(p.robot).publish(msg)
                    self.sent += 1
            except Exception:
                log.exception("ROS 2 site publisher")


class SiteWithRos2:
    """The viewer app handed to the server, with the site's ROS 2 publisher beside it."""

    def __init__(self, viewer: ViewerApp | None, site: SitePublisher) -> None:
        self.viewer, self.site = viewer, site

    def router(self, authenticate: Authenticate) -> APIRouter:
        return self.viewer.router(authenticate) if self.viewer is not None else APIRouter()

    def start(self, services: SiteServices) -> None:
        self.site.start(services)
        if self.viewer is not None:
            self.viewer.start(services)

    def stop(self) -> None:
        if self.viewer is not None:
            self.viewer.stop()
        self.site.stop()
