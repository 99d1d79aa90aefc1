"""A simulated robot as a ROS 2 robot appears (the demo of `irloc serve --ros2` and
`irloc agent --ros2 --sim`): a driver publishing its camera (`image_raw` mono8 and
`camera_info`), its wheel odometry (`odom`, and `<robot>/odom -> <robot>/base_link` on
`/tf`) and, as Gazebo's ground-truth plugin does, its true pose (`ground_truth`,
`nav_msgs/Odometry` in `map`), from one robot of the site's scenario (`SimRobotSource`).

The driver renders each frame `lag_s` behind real time, so that the site's LED states of a
frame's time reached the simulated world first (they come from the agent that hears them
over MQTT: `apply_leds`, the physical LEDs of the demo). Stamps are ROS time (wall clock).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterable

from agent.sim_source import SimRobotSource
from localizer.events import FrameObserved, OdometryMeasured, SpotsObserved
from localizer.odometry import integrate_odometry
from ros2.camera_info import camera_info_of
from ros2.messages import covariance6, header, new, pose_msg, transform_stamped, twist_msg
from ros2.settings import Ros2Settings
from ros2.transport import QOS_SENSOR_DATA, Ros2Participant
from sensors.ros2 import wall_minus_mono_ns

log = logging.getLogger(__name__)
CAMERA_FRAME = "camera_optical_frame"


class SimRos2Driver:
    """Publishes one simulated robot's sensors on ROS 2 under `settings.namespace`.

    Args:
        node: the DDS participant.
        source: the simulated robot (rendered frames; the light mode has no image).
        settings: topics and frames (the agent's, so both agree).
        lag_s: how far behind real time frames are rendered.
    """

    def __init__(
        self,
        node: Ros2Participant,
        source: SimRobotSource,
        settings: Ros2Settings,
        *,
        lag_s: float = 0.03,
    ) -> None:
        if source.light:
            raise ValueError("a ROS 2 driver publishes rendered images: not with --light")
        s = settings
        self.source = source
        self.settings = settings
        self.lag_ns = round(lag_s * 1e9)
        self.camera_frame = s.frame(CAMERA_FRAME)
        self.image_pub = node.publisher(
            s.topic(s.image_topic), "sensor_msgs/msg/Image", QOS_SENSOR_DATA
        )
        self.info_pub = node.publisher(
            s.topic(s.camera_info_topic), "sensor_msgs/msg/CameraInfo", QOS_SENSOR_DATA
        )
        self.odom_pub = node.publisher(
            s.topic(s.odom_topic), "nav_msgs/msg/Odometry", QOS_SENSOR_DATA
        )
        self.truth_pub = node.publisher(
            s.topic("ground_truth"), "nav_msgs/msg/Odometry", QOS_SENSOR_DATA
        )
        self.tf_pub = node.publisher(s.tf_topic, "tf2_msgs/msg/TFMessage", s.tf_qos)
        self.odom_pose = (0.0, 0.0, 0.0)
        self._last_odom_ns: int | None = None
        self.frames = 0
        self.render_ns = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, name=f"ros2-driver-{s.namespace}", daemon=True
        )

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)

    def apply_leds(self, t_ns: int, lit: Iterable[int] | None) -> None:
        """The site's LEDs from `t_ns` (monotonic) on: exactly `lit` (None: all)."""
        with self._lock:
            self.source.apply_leds(t_ns, None if lit is None else frozenset(lit))

    def _run(self) -> None:
        period = 1.0 / max(self.source.rig.spec.odometry_rate_hz, 50.0)
        while not self._stop.wait(period / 2):
            try:
                self.step(time.monotonic_ns() - self.lag_ns)
            except Exception:
                log.exception("%s: driver step failed", self.settings.namespace)

    def step(self, t_mono_ns: int) -> None:
        """Simulate to `t_mono_ns` and publish what came due."""
        t0 = time.perf_counter_ns()
        with self._lock:
            events = self.source.step(t_mono_ns)
        offset = wall_minus_mono_ns()
        for e in events:
            if isinstance(e, OdometryMeasured):
                self._odometry(e, e.t_ns + offset)
            elif isinstance(e, FrameObserved):
                self._frame(e, e.t_ns + offset)
                self.render_ns += time.perf_counter_ns() - t0
            elif isinstance(e, SpotsObserved):
                raise ValueError("SpotsObserved has no image to publish")

    def _odometry(self, e: OdometryMeasured, stamp: int) -> None:
        s = self.settings
        wheel_base = self.source.rig.geometry.wheel_base
        if self._last_odom_ns is not None:
            dt = (e.t_ns - self._last_odom_ns) / 1e9
            x, y, th = integrate_odometry(*self.odom_pose, e.v_left, e.v_right, dt, wheel_base)
            self.odom_pose = (float(x), float(y), float(th))
        self._last_odom_ns = e.t_ns
        v = 0.5 * (e.v_left + e.v_right)
        w = (e.v_right - e.v_left) / wheel_base
        pose = new(
            "geometry_msgs/msg/PoseWithCovariance",
            pose=pose_msg(self.odom_pose),
            covariance=covariance6([[1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 1e-4]]),  # type: ignore[arg-type]
        )
        self.odom_pub.publish(
            new(
                "nav_msgs/msg/Odometry",
                header=header(stamp, s.odom),
                child_frame_id=s.base,
                pose=pose,
                twist=twist_msg(v, w),
            )
        )
        tf = transform_stamped(stamp, s.odom, s.base, self.odom_pose)
        self.tf_pub.publish(new("tf2_msgs/msg/TFMessage", transforms=[tf]))

    def _frame(self, e: FrameObserved, stamp: int) -> None:
        s = self.settings
        h, w = e.image.shape
        self.image_pub.publish(
            new(
                "sensor_msgs/msg/Image",
                header=header(stamp, self.camera_frame),
                height=h,
                width=w,
                encoding="mono8",
                is_bigendian=0,
                step=w,
                data=e.image.tobytes(),
            )
        )
        self.info_pub.publish(camera_info_of(self.source.camera, stamp, self.camera_frame))
        truth = self.source.true_pose_at(e.t_ns)
        if truth is not None:
            self.truth_pub.publish(
                new(
                    "nav_msgs/msg/Odometry",
                    header=header(stamp, s.map_frame),
                    child_frame_id=s.base,
                    pose=new("geometry_msgs/msg/PoseWithCovariance", pose=pose_msg(truth)),
                )
            )
        self.frames += 1
