"""A robot's sensors from its ROS 2 topics: camera frames (`sensor_msgs/Image` or
`CompressedImage`, with `CameraInfo`), wheel speeds (the twist of `nav_msgs/Odometry`), its
`odom -> base_link` (from `/tf`) and `/initialpose`, as the localizer's events.

`Ros2Source` is a sensor source of the on-robot agent (`step`, `camera`, `geometry`, ...):
the DDS threads check and queue each input, the agent's sensor loop takes them in time order
with `step(t)`. Stamps are ROS time (the robot's wall clock, Unix ns); the events carry this
machine's monotonic clock as the agent's localizer does, and `ros_stamp(t)` gives a frame's
own stamp back for what is published about it.

Refused, each with a diagnostic naming what was wrong (`health`), never fed to the
localizer: an image whose encoding, step or size does not fit; frames while the camera_info
disagrees with the sensor.yaml; inputs stamped in the future (beyond
`future_tolerance_s`), out of order, or arriving after the agent already went past their
time; odometry in other frames than the configured ones; an /initialpose not in `map`.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from localizer.camera import CameraModel, T_body_camera_upward
from localizer.events import Event, FrameObserved, OdometryMeasured, RelocalizeRequested
from localizer.robot import RobotGeometry
from ros2.camera_info import camera_from_camera_info, camera_info_disagreement
from ros2.health import Health
from ros2.images import ImageError, gray8_from_compressed, gray8_from_image
from ros2.messages import pose2_of, stamp_ns
from ros2.settings import Ros2Settings
from ros2.transforms import TransformHistory
from ros2.transport import QOS_DEFAULT, Ros2Participant

log = logging.getLogger(__name__)


def wall_minus_mono_ns() -> int:
    """This machine's wall clock minus its monotonic clock (ROS time <-> agent time)."""
    return time.time_ns() - time.monotonic_ns()


class Ros2Source:
    """One robot's inputs from ROS 2 (see the module docstring).

    Args:
        node: the DDS participant.
        settings: topics, frames, QoS.
        geometry: the robot's wheel base and top speed.
        camera: the calibrated camera (sensor.yaml), or None to take the lens from the
            first camera_info (`wait_for_camera`).
        name: the robot's name (diagnostics, logs).
    """

    def __init__(
        self,
        node: Ros2Participant,
        settings: Ros2Settings,
        geometry: RobotGeometry,
        *,
        camera: CameraModel | None = None,
        name: str = "robot",
    ) -> None:
        self.node = node
        self.settings = settings
        self._geometry = geometry
        self._camera = camera
        self._from_sensor_yaml = camera is not None
        self.health = Health(name)
        self.odom_base = TransformHistory(settings.odom, settings.base)
        self.frames = 0
        self.odometry = 0
        self._events: list[Event] = []
        self._released_ns = 0
        self._last_image_ns = 0
        self._last_odom_ns = 0
        self._info_ok = True  # until a camera_info disagrees with the sensor.yaml
        self._camera_ready = threading.Event()
        if camera is not None:
            self._camera_ready.set()
        self._stamps: OrderedDict[int, int] = OrderedDict()
        self._lock = threading.Lock()
        self.led_sink: Callable[[int, frozenset[int] | None], None] | None = None
        s = settings
        image_type = "sensor_msgs/msg/CompressedImage" if s.compressed else "sensor_msgs/msg/Image"
        image_topic = s.topic(s.image_topic) + ("/compressed" if s.compressed else "")
        self.image_topic = image_topic
        node.subscribe(image_topic, image_type, self.on_image, s.image_qos)
        node.subscribe(
            s.topic(s.camera_info_topic), "sensor_msgs/msg/CameraInfo", self.on_camera_info,
            s.image_qos,
        )  # fmt: skip
        node.subscribe(s.topic(s.odom_topic), "nav_msgs/msg/Odometry", self.on_odometry, s.odom_qos)
        node.subscribe(s.tf_topic, "tf2_msgs/msg/TFMessage", self.on_tf, s.tf_qos)
        node.subscribe(
            s.topic(s.initialpose_topic), "geometry_msgs/msg/PoseWithCovarianceStamped",
            self.on_initialpose, QOS_DEFAULT,
        )  # fmt: skip

    # -- the agent's sensor source -------------------------------------------------------------
    @property
    def camera(self) -> CameraModel:
        if self._camera is None:
            raise RuntimeError("no camera yet: call wait_for_camera() first")
        return self._camera

    @property
    def geometry(self) -> RobotGeometry:
        return self._geometry

    @property
    def start_pose(self) -> tuple[float, float, float] | None:
        return None

    def wait_for_camera(self, timeout_s: float) -> CameraModel:
        """The camera, waiting for the first camera_info when there is no sensor.yaml.

        Raises:
            TimeoutError: naming the topic that stayed silent.
        """
        if not self._camera_ready.wait(timeout_s):
            raise TimeoutError(
                f"no sensor_msgs/CameraInfo on "
                f"{self.settings.topic(self.settings.camera_info_topic)} "
                f"within {timeout_s:.0f} s (or give the camera's sensor.yaml)"
            )
        return self.camera

    def step(self, t_ns: int) -> list[Event]:
        """The inputs stamped up to `t_ns` (monotonic), in time order."""
        with self._lock:
            self._events.sort(key=lambda e: e.t_ns)
            n = next((i for i, e in enumerate(self._events) if e.t_ns > t_ns), len(self._events))
            due, self._events = self._events[:n], self._events[n:]
            self._released_ns = max(self._released_ns, t_ns)
        return due

    def apply_leds(self, t_ns: int, lit: Iterable[int] | None) -> None:
        """A real robot's camera sees the real LEDs: nothing to do (`led_sink`: the
        simulated world of a demo driver, which has no real LEDs)."""
        if self.led_sink is not None:
            self.led_sink(t_ns, None if lit is None else frozenset(lit))

    def true_pose_at(self, t_ns: int) -> tuple[float, float, float] | None:
        return None

    def ros_stamp(self, t_mono_ns: int) -> int:
        """The ROS stamp of the frame the agent knows as `t_mono_ns` (its exposure)."""
        with self._lock:
            stamp = self._stamps.get(t_mono_ns)
        return stamp if stamp is not None else t_mono_ns + wall_minus_mono_ns()

    # -- checks shared by the inputs ------------------------------------------------------------
    def _admit(self, key: str, t_ros: int, last_ns: int) -> int | None:
        """The monotonic time of an input stamped `t_ros`, or None (reported) when it is in the
        future, out of order or too late for the agent."""
        offset = wall_minus_mono_ns()
        ahead = t_ros - (time.monotonic_ns() + offset)
        if ahead > self.settings.future_tolerance_s * 1e9:
            self.health.report(
                key, "error",
                f"stamped {ahead / 1e9:.3f} s in the future "
                "(is the robot's clock synchronised?): refused",
            )  # fmt: skip
            return None
        if t_ros <= last_ns:
            self.health.report(
                key, "error",
                f"out of order: stamp {(last_ns - t_ros) / 1e6:.1f} ms before the previous "
                "one: refused",
            )  # fmt: skip
            return None
        t_mono = t_ros - offset
        if t_mono <= self._released_ns:
            self.health.report(
                key, "warn",
                f"arrived {(self._released_ns - t_mono) / 1e6:.0f} ms after the agent passed its "
                "time (raise --hold above the transport latency): dropped",
            )  # fmt: skip
            return None
        return t_mono

    def _queue(self, event: Event) -> None:
        with self._lock:
            self._events.append(event)

    # -- callbacks (DDS threads) ----------------------------------------------------------------
    def on_image(self, msg: Any) -> None:
        t_ros = stamp_ns(msg.header.stamp)
        if self._camera is None:
            self.health.report("image", "warn", "frames wait for the first camera_info")
            return
        if not self._info_ok:
            return  # camera_info disagrees with sensor.yaml: reported under camera_info
        size = (self._camera.width, self._camera.height)
        try:
            if self.settings.compressed:
                image = gray8_from_compressed(msg, expected_size=size)
            else:
                image = gray8_from_image(msg, expected_size=size)
        except ImageError as exc:
            self.health.report("image", "error", f"{self.image_topic}: {exc}: refused")
            return
        with self._lock:
            last = self._last_image_ns
        t_mono = self._admit("image", t_ros, last)
        if t_mono is None:
            return
        with self._lock:
            self._last_image_ns = t_ros
            self._stamps[t_mono] = t_ros
            while len(self._stamps) > 300:
                self._stamps.popitem(last=False)
        self.health.clear("image")
        self._queue(FrameObserved(t_mono, image))
        self.frames += 1

    def on_camera_info(self, msg: Any) -> None:
        topic = self.settings.topic(self.settings.camera_info_topic)
        if self._from_sensor_yaml:
            assert self._camera is not None
            diffs = camera_info_disagreement(msg, self._camera)
            self._info_ok = not diffs
            if diffs:
                self.health.report(
                    "camera_info", "error",
                    f"{topic} disagrees with sensor.yaml ({'; '.join(diffs)}): frames refused "
                    "until they agree (recalibrate, or fix the driver's camera_info_url)",
                )  # fmt: skip
            else:
                self.health.clear("camera_info")
            return
        if self._camera is not None:
            return
        try:
            mount = T_body_camera_upward(height=self.settings.camera_height_m)
            self._camera = camera_from_camera_info(msg, mount)
        except ValueError as exc:
            self.health.report("camera_info", "error", f"{topic}: {exc}")
            return
        self._info_ok = True
        self._camera_ready.set()

    def on_odometry(self, msg: Any) -> None:
        s = self.settings
        frame, child = str(msg.header.frame_id), str(msg.child_frame_id)
        if (frame, child) != (s.odom, s.base):
            self.health.report(
                "odom", "error",
                f"{s.topic(s.odom_topic)} is {frame!r} -> {child!r}, expected {s.odom!r} -> "
                f"{s.base!r} (set odom_frame/base_frame): refused",
            )  # fmt: skip
            return
        v = float(msg.twist.twist.linear.x)
        w = float(msg.twist.twist.angular.z)
        if not (math.isfinite(v) and math.isfinite(w)):
            self.health.report("odom", "error", f"non-finite twist ({v}, {w}): refused")
            return
        t_ros = stamp_ns(msg.header.stamp)
        with self._lock:
            last = self._last_odom_ns
        t_mono = self._admit("odom", t_ros, last)
        if t_mono is None:
            return
        with self._lock:
            self._last_odom_ns = t_ros
        self.health.clear("odom")
        half = 0.5 * self._geometry.wheel_base * w
        self._queue(OdometryMeasured(t_mono, v - half, v + half))
        self.odometry += 1

    def on_tf(self, msg: Any) -> None:
        s = self.settings
        for tf in msg.transforms:
            if str(tf.header.frame_id) == s.odom and str(tf.child_frame_id) == s.base:
                self.odom_base.add(stamp_ns(tf.header.stamp), pose2_of(tf.transform))

    def on_initialpose(self, msg: Any) -> None:
        s = self.settings
        frame = str(msg.header.frame_id)
        if frame != s.map_frame:
            self.health.report(
                "initialpose", "error",
                f"{s.topic(s.initialpose_topic)} in frame {frame!r}, expected "
                f"{s.map_frame!r}: ignored",
            )  # fmt: skip
            return
        near = pose2_of(msg.pose.pose)
        if not all(np.isfinite(near)):
            self.health.report("initialpose", "error", f"non-finite pose {near}: ignored")
            return
        self.health.clear("initialpose")
        log.info("%s: relocalizing near %s (initialpose)", self.health.name, near)
        with self._lock:
            t = max(self._released_ns, time.monotonic_ns() - 1) + 1
            self._events.append(RelocalizeRequested(t, near))
