"""A robot's camera and wheel odometry from its ROS 2 topics, as a `FrameSource`:
`sensor_msgs/Image` (or `CompressedImage`) with `CameraInfo`, and `nav_msgs/Odometry`
(its twist gives the wheel speeds) or the wheel joints of `sensor_msgs/JointState`,
delivered as `FrameObserved` / `OdometryMeasured` to `sink(robot, event)` from the DDS
participant's reader thread (docs/ros2.md).

Stamps are ROS time (the robot's wall clock, Unix ns); events carry this machine's
monotonic clock, as the agent's localizer does, and `ros_stamp(t)` gives a frame's own
stamp back for what is published about it.

Refused, each with a diagnostic naming what was wrong (`health`), never delivered: an image
whose encoding, step or size does not fit; frames while the camera_info disagrees with the
sensor.yaml; inputs stamped in the future (beyond `future_tolerance_s`) or out of order;
odometry in other frames than the configured ones.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

from localizer.camera import CameraModel, T_body_camera_upward
from localizer.events import FrameObserved, OdometryMeasured
from localizer.robot import RobotGeometry
from ros2.camera_info import camera_from_camera_info, camera_info_disagreement
from ros2.health import Health
from ros2.images import ImageError, gray8_from_compressed, gray8_from_image
from ros2.messages import stamp_ns
from ros2.settings import Ros2Settings
from ros2.transport import Ros2Participant
from sensors.sources import SensorEvent, SensorSink


def wall_minus_mono_ns() -> int:
    """This machine's wall clock minus its monotonic clock (ROS time <-> agent time)."""
    return time.time_ns() - time.monotonic_ns()


class Ros2Source:
    """One robot's camera and odometry from ROS 2 (see the module docstring).

    Args:
        robot: the robot's name (the sink's first argument, diagnostics, logs).
        node: the DDS participant.
        settings: topics, frames, QoS.
        geometry: the robot's wheel base (twist to wheel speeds).
        camera: the calibrated camera (sensor.yaml), or None to take the lens from the
            first camera_info (`wait_for_camera`).
        health: where problems are reported (a new one by default).
    """

    def __init__(
        self,
        robot: str,
        node: Ros2Participant,
        settings: Ros2Settings,
        geometry: RobotGeometry,
        *,
        camera: CameraModel | None = None,
        health: Health | None = None,
    ) -> None:
        self.robot = robot
        self.settings = settings
        self.geometry = geometry
        self.health = health or Health(robot)
        self._camera = camera
        self._from_sensor_yaml = camera is not None
        self._info_ok = True  # until a camera_info disagrees with the sensor.yaml
        self._camera_ready = threading.Event()
        if camera is not None:
            self._camera_ready.set()
        self._sink: SensorSink | None = None
        self._last_image_ns = 0
        self._last_odom_ns = 0
        self._stamps: OrderedDict[int, int] = OrderedDict()
        self._lock = threading.Lock()
        self.frames = 0
        self.odometry = 0
        s = settings
        image_type = "sensor_msgs/msg/CompressedImage" if s.compressed else "sensor_msgs/msg/Image"
        self.image_topic = s.topic(s.image_topic) + ("/compressed" if s.compressed else "")
        node.subscribe(self.image_topic, image_type, self.on_image, s.image_qos)
        node.subscribe(
            s.topic(s.camera_info_topic),
            "sensor_msgs/msg/CameraInfo",
            self.on_camera_info,
            s.image_qos,
        )
        if s.wheel_joints:
            self.joints = tuple(j.strip() for j in s.wheel_joints.split(","))
            node.subscribe(
                s.topic(s.joint_states_topic),
                "sensor_msgs/msg/JointState",
                self.on_joint_states,
                s.odom_qos,
            )
        else:
            node.subscribe(
                s.topic(s.odom_topic), "nav_msgs/msg/Odometry", self.on_odometry, s.odom_qos
            )

    # -- FrameSource --------------------------------------------------------------------------
    @property
    def robots(self) -> Sequence[str]:
        return (self.robot,)

    def start(self, sink: SensorSink) -> None:
        self._sink = sink

    def stop(self) -> None:
        self._sink = None

    # -- the camera ---------------------------------------------------------------------------
    @property
    def camera(self) -> CameraModel:
        if self._camera is None:
            raise RuntimeError("no camera yet: call wait_for_camera() first")
        return self._camera

    def wait_for_camera(self, timeout_s: float) -> CameraModel:
        """The camera, waiting for the first camera_info when there is no sensor.yaml.

        Raises:
            TimeoutError: naming the topic that stayed silent.
        """
        if not self._camera_ready.wait(timeout_s):
            topic = self.settings.topic(self.settings.camera_info_topic)
            raise TimeoutError(
                f"no sensor_msgs/CameraInfo on {topic} within {timeout_s:.0f} s "
                "(or give the camera's sensor.yaml)"
            )
        return self.camera

    def ros_stamp(self, t_mono_ns: int) -> int:
        """The ROS stamp of the frame the agent knows as `t_mono_ns` (its exposure)."""
        with self._lock:
            stamp = self._stamps.get(t_mono_ns)
        return stamp if stamp is not None else t_mono_ns + wall_minus_mono_ns()

    # -- checks shared by the inputs ------------------------------------------------------------
    def _admit(self, key: str, t_ros: int, last_ns: int) -> int | None:
        """The monotonic time of an input stamped `t_ros`, or None (reported) when it is in
        the future or out of order."""
        offset = wall_minus_mono_ns()
        ahead = t_ros - (time.monotonic_ns() + offset)
        if ahead > self.settings.future_tolerance_s * 1e9:
            self.health.report(
                key,
                "error",
                f"stamped {ahead / 1e9:.3f} s in the future "
                "(is the robot's clock synchronised?): refused",
            )
            return None
        if t_ros <= last_ns:
            self.health.report(
                key,
                "error",
                f"out of order: stamp {(last_ns - t_ros) / 1e6:.1f} ms before the previous "
                "one: refused",
            )
            return None
        return t_ros - offset

    def _deliver(self, event: SensorEvent) -> None:
        sink = self._sink
        if sink is not None:
            sink(self.robot, event)

    # -- callbacks (the participant's reader thread) ------------------------------------------
    def on_image(self, msg: Any) -> None:
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
        t_ros = stamp_ns(msg.header.stamp)
        with self._lock:
            t_mono = self._admit("image", t_ros, self._last_image_ns)
            if t_mono is None:
                return
            self._last_image_ns = t_ros
            self._stamps[t_mono] = t_ros
            while len(self._stamps) > 300:
                self._stamps.popitem(last=False)
        self.health.clear("image")
        self.frames += 1
        self._deliver(FrameObserved(t_mono, image))

    def on_camera_info(self, msg: Any) -> None:
        topic = self.settings.topic(self.settings.camera_info_topic)
        if self._from_sensor_yaml:
            assert self._camera is not None
            diffs = camera_info_disagreement(msg, self._camera)
            self._info_ok = not diffs
            if diffs:
                self.health.report(
                    "camera_info",
                    "error",
                    f"{topic} disagrees with sensor.yaml ({'; '.join(diffs)}): frames refused "
                    "until they agree (recalibrate, or fix the driver's camera_info_url)",
                )
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
        self._camera_ready.set()

    def on_odometry(self, msg: Any) -> None:
        s = self.settings
        frame, child = str(msg.header.frame_id), str(msg.child_frame_id)
        if (frame, child) != (s.odom, s.base):
            self.health.report(
                "odom",
                "error",
                f"{s.topic(s.odom_topic)} is {frame!r} -> {child!r}, expected {s.odom!r} -> "
                f"{s.base!r} (set odom_frame/base_frame): refused",
            )
            return
        v = float(msg.twist.twist.linear.x)
        w = float(msg.twist.twist.angular.z)
        if not (abs(v) < 1e3 and abs(w) < 1e3):  # also catches NaN
            self.health.report("odom", "error", f"twist ({v}, {w}) is not a speed: refused")
            return
        half = 0.5 * self.geometry.wheel_base * w
        self._wheels("odom", stamp_ns(msg.header.stamp), v - half, v + half)

    def on_joint_states(self, msg: Any) -> None:
        """Wheel speeds from the two wheel joints' velocities (rad/s) and the wheel radius."""
        topic = self.settings.topic(self.settings.joint_states_topic)
        names = [str(n) for n in msg.name]
        if not all(j in names for j in self.joints):
            if any(j in names for j in self.joints):  # a message of other joints is not ours
                self.health.report(
                    "odom", "error", f"{topic}: one wheel joint of {self.joints} missing"
                )
            return
        idx = [names.index(j) for j in self.joints]
        vel = list(msg.velocity)
        if len(vel) != len(names):
            self.health.report(
                "odom",
                "error",
                f"{topic}: {len(vel)} velocities for {len(names)} joints: refused",
            )
            return
        r = self.settings.wheel_radius_m
        left, right = float(vel[idx[0]]) * r, float(vel[idx[1]]) * r
        if not (abs(left) < 1e3 and abs(right) < 1e3):
            self.health.report("odom", "error", f"{topic}: wheel speeds ({left}, {right}): refused")
            return
        self._wheels("odom", stamp_ns(msg.header.stamp), left, right)

    def _wheels(self, key: str, t_ros: int, v_left: float, v_right: float) -> None:
        with self._lock:
            t_mono = self._admit(key, t_ros, self._last_odom_ns)
            if t_mono is None:
                return
            self._last_odom_ns = t_ros
        self.health.clear(key)
        self.odometry += 1
        self._deliver(OdometryMeasured(t_mono, v_left, v_right))
