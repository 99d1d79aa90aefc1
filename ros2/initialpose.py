"""`/initialpose` (RViz's "2D Pose Estimate"): a request to relocalize near a pose in `map`."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

from ros2.health import Health
from ros2.messages import Pose2, pose2_of
from ros2.settings import Ros2Settings
from ros2.transport import QOS_DEFAULT, Ros2Participant

log = logging.getLogger(__name__)


class InitialPoseListener:
    """Calls `on_request((x, y, yaw))` for each valid `/initialpose`; one in another frame
    than `map`, or not finite, is reported to `health` and ignored."""

    def __init__(
        self,
        node: Ros2Participant,
        settings: Ros2Settings,
        health: Health,
        on_request: Callable[[Pose2], None],
    ) -> None:
        self.settings, self.health, self.on_request = settings, health, on_request
        self.topic = settings.topic(settings.initialpose_topic)
        node.subscribe(
            self.topic,
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            self.on_message,
            QOS_DEFAULT,
        )

    def on_message(self, msg: Any) -> None:
        frame = str(msg.header.frame_id)
        if frame != self.settings.map_frame:
            self.health.report(
                "initialpose",
                "error",
                f"{self.topic} in frame {frame!r}, expected {self.settings.map_frame!r}: ignored",
            )
            return
        near = pose2_of(msg.pose.pose)
        if not all(math.isfinite(v) for v in near):
            self.health.report("initialpose", "error", f"non-finite pose {near}: ignored")
            return
        self.health.clear("initialpose")
        log.info("%s: relocalizing near %s (initialpose)", self.health.name, near)
        self.on_request(near)
