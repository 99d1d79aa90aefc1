"""What irloc publishes on a robot's ROS 2 graph, from the localizer's outputs:

- `/irloc/pose` (`geometry_msgs/PoseWithCovarianceStamped` in `map`), stamped at the
  frame's exposure, with the published covariance (x, y, yaw; z, roll and pitch flagged
  unknown): the one REST, MQTT and VDA 5050 carry, about 95 % of errors inside its 2-sigma
  ellipse (docs/quality.md);
- `/tf` `map -> odom`: the pose composed with the robot's own `odom -> base_link` at that
  same stamp (REP-105), stamped `transform_tolerance_s` later as AMCL does; a pose whose
  `odom -> base_link` does not arrive within `max_wait_transform_s` of the pose (a reader
  that stalled catches up) gives no transform and a diagnostic (never a transform built
  from the wrong odometry);
- `/diagnostics` (`diagnostic_msgs/DiagnosticArray`, 1/s and at each mode change): the
  mode, the pose's `quality`, `deviation_m` (95 % radius) and `reason` code, the landmarks
  in use and expected, why there is no fix (the reason's sentence), each input problem;
- the landmark map (`visualization_msgs/MarkerArray`, transient local: RViz opened later
  still gets it), at each new map.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from localizer.events import Mode, NoPose, PoseEstimate
from localizer.landmark_map import LandmarkMap
from ros2.health import LEVEL_BYTE, Health, Level
from ros2.messages import (
    compose,
    covariance6,
    header,
    inverse,
    new,
    pose2_of,
    pose_msg,
    stamp_ns,
    transform_stamped,
)
from ros2.settings import Ros2Settings
from ros2.transforms import TransformHistory
from ros2.transport import QOS_DEFAULT, Ros2Participant

log = logging.getLogger(__name__)

WHY_NO_FIX: dict[Mode, str] = {
    "identifying": "identifying the landmarks in view (switching their LEDs)",
    "dead_reckoning": "no landmark in view: dead reckoning on the wheel odometry",
    "lost": "lost: no landmark in view agrees with the map and odometry (send /initialpose)",
    "landmark": "",
}
LANDMARK_RGBA = (1.0, 0.55, 0.0, 0.9)


class Ros2Outputs:
    """Publishes one robot's localization (see the module docstring).

    Args:
        node: the DDS participant.
        settings: topics, frames, QoS.
        health: the input problems to report.
        ros_stamp: the ROS stamp of a frame the agent knows by its monotonic time.
        name: the robot's name (`hardware_id` of its diagnostics).

    Attributes:
        odom_base: the robot's own `odom -> base_link`, as received on `/tf`.
    """

    def __init__(
        self,
        node: Ros2Participant,
        settings: Ros2Settings,
        health: Health,
        ros_stamp: Callable[[int], int],
        *,
        name: str,
    ) -> None:
        s = settings
        self.settings = settings
        self.health = health
        self.odom_base = TransformHistory(s.odom, s.base)
        self.ros_stamp = ros_stamp
        node.subscribe(s.tf_topic, "tf2_msgs/msg/TFMessage", self.on_tf, s.tf_qos)
        self.name = name
        self.pose_pub = node.publisher(
            s.topic(s.pose_topic), "geometry_msgs/msg/PoseWithCovarianceStamped", s.pose_qos
        )
        self.tf_pub = node.publisher(s.tf_topic, "tf2_msgs/msg/TFMessage", s.tf_qos)
        self.diag_pub = node.publisher(
            s.diagnostics_topic, "diagnostic_msgs/msg/DiagnosticArray", QOS_DEFAULT
        )
        self.marker_pub = node.publisher(
            s.topic(s.markers_topic), "visualization_msgs/msg/MarkerArray", s.markers_qos
        )
        self.mode: Mode | None = None
        self.has_map = False
        self.last: PoseEstimate | None = None
        self.last_output: PoseEstimate | NoPose | None = None  # with a pose or without
        self.poses = 0
        self.transforms = 0
        self._waiting: deque[tuple[int, PoseEstimate, int]] = deque()  # stamp, pose, queued
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"ros2-out-{name}", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)

    def on_tf(self, msg: Any) -> None:
        """Keep the robot's own `odom -> base_link` (the one transform irloc needs)."""
        s = self.settings
        for tf in msg.transforms:
            if str(tf.header.frame_id) == s.odom and str(tf.child_frame_id) == s.base:
                self.odom_base.add(stamp_ns(tf.header.stamp), pose2_of(tf.transform))

    # -- from the agent (its sensor thread) ----------------------------------------------------
    def on_map(self, landmark_map: LandmarkMap) -> None:
        self.has_map = True
        self.marker_pub.publish(self.markers(landmark_map))

    def on_pose(self, output: PoseEstimate | NoPose) -> None:
        changed = output.mode != self.mode  # a new reason waits for the 1/s status
        self.mode = output.mode
        self.last_output = output
        if isinstance(output, PoseEstimate) and output.mode in self.settings.publish_modes:
            stamp = self.ros_stamp(output.t_ns)
            self.last = output
            self.pose_pub.publish(self.pose_message(output, stamp))
            self.poses += 1
            if self.settings.publish_tf:
                with self._lock:
                    self._waiting.append((stamp, output, time.monotonic_ns()))
                self._flush_transforms()
        if changed:
            self.publish_diagnostics()

    # -- map -> odom ---------------------------------------------------------------------------
    def _flush_transforms(self) -> None:
        """Publish `map -> odom` for the poses whose `odom -> base_link` is known (the newest
        wins), report those that waited too long."""
        s = self.settings
        now = time.monotonic_ns()
        latest: tuple[int, tuple[float, float, float]] | None = None
        with self._lock:
            while self._waiting:
                stamp, est, queued = self._waiting[0]
                T_odom_base = self.odom_base.at(stamp)
                if T_odom_base is not None:
                    T_map_base = (est.x, est.y, est.theta)
                    latest = (stamp, compose(T_map_base, inverse(T_odom_base)))
                    self._waiting.popleft()
                    continue
                if now - queued > s.max_wait_transform_s * 1e9:
                    self.health.report(
                        "transform",
                        "error",
                        self.odom_base.describe_gap(stamp) + ": no map -> odom for this pose",
                    )
                    self._waiting.popleft()
                    continue
                break
        if latest is not None:
            stamp, T_map_odom = latest
            t_pub = stamp + round(s.transform_tolerance_s * 1e9)
            tf = transform_stamped(t_pub, s.map_frame, s.odom, T_map_odom)
            self.tf_pub.publish(new("tf2_msgs/msg/TFMessage", transforms=[tf]))
            self.transforms += 1
            self.health.clear("transform")

    # -- messages ------------------------------------------------------------------------------
    def pose_message(self, est: PoseEstimate, stamp: int) -> Any:
        return pose_with_covariance(
            (est.x, est.y, est.theta), est.covariance, stamp, self.settings.map_frame
        )

    def markers(self, landmark_map: LandmarkMap) -> Any:
        return landmark_markers(landmark_map, self.settings.map_frame, time.time_ns())

    def status(self) -> tuple[Level, str, list[tuple[str, str]]]:
        """The level, message and key-values of this robot's diagnostic status."""
        problems = self.health.problems()
        values: list[tuple[str, str]] = [("mode", self.mode or "starting")]
        out = self.last_output
        if out is not None:
            dev = "" if out.deviation_m is None else f"{out.deviation_m:.4f}"
            quality = "" if out.quality is None else f"{out.quality:.3f}"
            values += [("quality", quality), ("deviation_m", dev), ("reason", out.reason or "")]
        last = self.last
        if last is not None and last.mode == self.mode:
            values += [
                ("landmarks_in_use", " ".join(map(str, last.landmark_ids))),
                ("landmarks_expected", " ".join(map(str, last.expected_ids))),
                ("sigma_xy_m", f"{max(last.covariance[0, 0], last.covariance[1, 1]) ** 0.5:.4f}"),
            ]
        values += [("poses", str(self.poses)), ("transforms", str(self.transforms))]
        values += [(f"problem.{p.key}", f"{p.message} (x{p.count})") for p in problems]
        if not self.has_map:
            return "warn", "no landmark map from the site yet", values
        if problems and problems[0].level == "error":
            return "error", problems[0].message, values
        if self.mode is None:
            return "warn", "no camera frame localized yet", values
        why = WHY_NO_FIX[self.mode]
        if out is not None and out.reason_text and self.mode != "landmark":
            why = out.reason_text + (" (send /initialpose)" if self.mode == "lost" else "")
        if why:
            return "warn", why, values
        if problems:
            return "warn", problems[0].message, values
        used = len(last.landmark_ids) if last is not None else 0
        return "ok", f"localized on {used} landmarks", values

    def publish_diagnostics(self) -> None:
        level, message, values = self.status()
        st = new(
            "diagnostic_msgs/msg/DiagnosticStatus",
            level=LEVEL_BYTE[level],
            name=f"irloc: {self.name} localization",
            message=message,
            hardware_id=self.name,
            values=[new("diagnostic_msgs/msg/KeyValue", key=k, value=v) for k, v in values],
        )
        self.diag_pub.publish(
            new(
                "diagnostic_msgs/msg/DiagnosticArray",
                header=header(time.time_ns(), ""),
                status=[st],
            )
        )

    def _run(self) -> None:
        next_diag = 0.0
        while not self._stop.wait(0.05):
            self._flush_transforms()
            if time.monotonic() >= next_diag:
                next_diag = time.monotonic() + 1.0
                try:
                    self.publish_diagnostics()
                except Exception:
                    log.exception("%s: diagnostics failed", self.name)


def pose_with_covariance(
    pose: tuple[float, float, float], covariance: Any, stamp: int, frame: str
) -> Any:
    """geometry_msgs/PoseWithCovarianceStamped of a planar pose and its (3, 3) covariance."""
    return new(
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        header=header(stamp, frame),
        pose=new(
            "geometry_msgs/msg/PoseWithCovariance",
            pose=pose_msg(pose),
            covariance=covariance6(covariance),
        ),
    )


def landmark_markers(landmark_map: LandmarkMap, frame: str, t_ns: int) -> Any:
    """One cylinder and one id label a landmark, after a DELETEALL of the namespace."""
    hdr = header(t_ns, frame)
    color = new(
        "std_msgs/msg/ColorRGBA",
        r=LANDMARK_RGBA[0],
        g=LANDMARK_RGBA[1],
        b=LANDMARK_RGBA[2],
        a=LANDMARK_RGBA[3],
    )
    white = new("std_msgs/msg/ColorRGBA", r=1.0, g=1.0, b=1.0, a=1.0)
    q = new("geometry_msgs/msg/Quaternion", w=1.0)
    out = [new("visualization_msgs/msg/Marker", header=hdr, ns="irloc_landmarks", action=3)]
    for lid, p in zip(landmark_map.ids.tolist(), landmark_map.positions.tolist(), strict=True):
        pos = new("geometry_msgs/msg/Point", x=p[0], y=p[1], z=p[2])
        out.append(
            new(
                "visualization_msgs/msg/Marker",
                header=hdr,
                ns="irloc_landmarks",
                id=int(lid),
                type=3,
                action=0,
                color=color,
                frame_locked=True,
                pose=new("geometry_msgs/msg/Pose", position=pos, orientation=q),
                scale=new("geometry_msgs/msg/Vector3", x=0.12, y=0.12, z=0.03),
            )
        )
        label_pos = new("geometry_msgs/msg/Point", x=p[0], y=p[1], z=p[2] - 0.12)
        out.append(
            new(
                "visualization_msgs/msg/Marker",
                header=hdr,
                ns="irloc_landmark_ids",
                id=int(lid),
                type=9,
                action=0,
                text=str(lid),
                color=white,
                frame_locked=True,
                pose=new("geometry_msgs/msg/Pose", position=label_pos, orientation=q),
                scale=new("geometry_msgs/msg/Vector3", z=0.15),
            )
        )
    return new("visualization_msgs/msg/MarkerArray", markers=out)
