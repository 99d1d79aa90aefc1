"""Topic names, frame ids and QoS of irloc on ROS 2, with the defaults Nav2 users expect.

Names resolve as ROS resolves them: an absolute name (`/tf`) stays, a relative one
(`odom`) goes under the namespace (`/r1/odom`); frames other than `map` get the namespace as
prefix (`r1/odom`, `r1/base_link`), as multi-robot Nav2 launches set `frame_prefix`.
`Ros2Settings.with_overrides(["image_qos=reliable", "odom_topic=wheel/odom"])` changes any
field from the command line (`--ros2-param`).
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field

from ros2.transport import QOS_DEFAULT, QOS_LATCHED, QosProfile

_NAME = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")


def check_name(what: str, name: str) -> str:
    """A ROS name (topic, namespace or frame id) or ValueError naming `what`."""
    if not _NAME.match(name):
        raise ValueError(f"{what} {name!r} is not a valid ROS name (letters, digits, _ and /)")
    return name


@dataclass(frozen=True)
class Ros2Settings:
    """irloc on one robot's ROS 2 graph (defaults: Nav2's names and QoS).

    Attributes:
        namespace: the robot's namespace ("" or e.g. "r1").
        image_topic: `sensor_msgs/Image` (best effort: matches a reliable driver too).
        compressed: read `<image_topic>/compressed` (`sensor_msgs/CompressedImage`) instead.
        camera_info_topic: `sensor_msgs/CameraInfo`.
        odom_topic: `nav_msgs/Odometry` (its twist gives the wheel speeds).
        wheel_joints: "LEFT,RIGHT" joint names: take the wheel speeds from
            `sensor_msgs/JointState` on `joint_states_topic` instead of the odometry
            (velocities in rad/s times `wheel_radius_m`); "" (default): from `odom_topic`.
        joint_states_topic, wheel_radius_m: with `wheel_joints`.
        pose_topic: `geometry_msgs/PoseWithCovarianceStamped` published in `map_frame`.
        initialpose_topic: RViz's "2D Pose Estimate" (relocalize near that pose).
        markers_topic: the landmark map, `visualization_msgs/MarkerArray` (transient local).
        diagnostics_topic, tf_topic: absolute as ROS tools expect.
        map_frame, odom_frame, base_frame: REP-105 frames (odom and base get the namespace).
        image_qos, odom_qos: the readers' QoS, best effort (matches best-effort and reliable
            drivers) with room for a second of 10 Hz images and 100 Hz odometry: a reader
            thread that stalls that long loses no odometry (the agent waits for it,
            `AgentConfig.input_wait_s`).
        transform_tolerance_s: `map -> odom` is stamped this much after the frame it was
            computed from (AMCL's `transform_tolerance`: a tf lookup at "now" finds it).
        future_tolerance_s: an input stamped further ahead of this machine's clock is refused.
        max_wait_transform_s: how long a pose waits for `odom -> base_link` at its stamp
            (from when the pose was computed).
        camera_height_m: optical centre above the floor when the lens comes from camera_info
            (no sensor.yaml): an upward camera on the robot's centre.
        publish_tf: publish `map -> odom` (off when robot_localization fuses the pose topic
            and publishes the transform itself).
        publish_modes: the localizer modes whose poses go out on the pose topic and as
            `map -> odom` (not `identifying` or `lost`: the localizer does not know where
            the robot is, and a Nav2 stack must not drive on its guess).
    """

    namespace: str = ""
    image_topic: str = "image_raw"
    compressed: bool = False
    camera_info_topic: str = "camera_info"
    odom_topic: str = "odom"
    wheel_joints: str = ""
    joint_states_topic: str = "joint_states"
    wheel_radius_m: float = 0.0
    pose_topic: str = "irloc/pose"
    initialpose_topic: str = "initialpose"
    markers_topic: str = "irloc/landmarks"
    diagnostics_topic: str = "/diagnostics"
    tf_topic: str = "/tf"
    map_frame: str = "map"
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    image_qos: QosProfile = field(default=QosProfile("best_effort", "volatile", 10))
    odom_qos: QosProfile = field(default=QosProfile("best_effort", "volatile", 100))
    pose_qos: QosProfile = field(default=QOS_DEFAULT)
    tf_qos: QosProfile = field(default=QosProfile("reliable", "volatile", 100))
    markers_qos: QosProfile = field(default=QOS_LATCHED)
    transform_tolerance_s: float = 1.0
    future_tolerance_s: float = 0.1
    max_wait_transform_s: float = 0.2
    camera_height_m: float = 0.3
    publish_tf: bool = True
    publish_modes: tuple[str, ...] = ("landmark", "dead_reckoning")

    def __post_init__(self) -> None:
        if self.namespace:
            check_name("namespace", self.namespace)
        for f in dataclasses.fields(self):
            if f.name.endswith(("_topic", "_frame")):
                check_name(f.name, getattr(self, f.name))
        if self.wheel_joints:
            joints = [j.strip() for j in self.wheel_joints.split(",")]
            if len(joints) != 2 or not all(joints):
                raise ValueError(
                    f"wheel_joints must be LEFT,RIGHT joint names: {self.wheel_joints!r}"
                )
            if not 0 < self.wheel_radius_m <= 2:
                raise ValueError(
                    f"wheel_joints needs wheel_radius_m in (0, 2] m: {self.wheel_radius_m}"
                )
        for name in ("transform_tolerance_s", "future_tolerance_s", "max_wait_transform_s"):
            if not 0 <= getattr(self, name) <= 10:
                raise ValueError(f"{name} must be in [0, 10] s, got {getattr(self, name)}")

    def topic(self, name: str) -> str:
        """The resolved topic of a relative or absolute name."""
        if name.startswith("/"):
            return name
        ns = self.namespace.strip("/")
        return f"/{ns}/{name}" if ns else f"/{name}"

    def frame(self, name: str) -> str:
        """A frame id with the namespace prefix (`map` is shared by every robot)."""
        ns = self.namespace.strip("/")
        return f"{ns}/{name}" if ns and name != self.map_frame else name

    @property
    def odom(self) -> str:
        return self.frame(self.odom_frame)

    @property
    def base(self) -> str:
        return self.frame(self.base_frame)

    def with_overrides(self, pairs: list[str]) -> Ros2Settings:
        """These settings with `key=value` pairs applied (QoS: `reliable`, `best_effort`,
        optionally `,transient_local` and `,depth=N`).

        Raises:
            ValueError: an unknown key or a bad value, named.
        """
        fields = {f.name: f for f in dataclasses.fields(self)}
        changes: dict[str, object] = {}
        for pair in pairs:
            key, sep, value = pair.partition("=")
            key = key.strip()
            if not sep or key not in fields:
                raise ValueError(
                    f"--ros2-param {pair!r}: expected KEY=VALUE with KEY one of {sorted(fields)}"
                )
            current = getattr(self, key)
            if isinstance(current, tuple):
                changes[key] = tuple(v.strip() for v in value.split(",") if v.strip())
            elif isinstance(current, QosProfile):
                changes[key] = parse_qos(value)
            elif isinstance(current, bool):
                changes[key] = value.lower() in ("1", "true", "yes", "on")
            elif isinstance(current, float):
                try:
                    changes[key] = float(value)
                except ValueError:
                    raise ValueError(f"--ros2-param {key}: {value!r} is not a number") from None
            else:
                changes[key] = value
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


def parse_qos(text: str) -> QosProfile:
    """`reliable|best_effort[,volatile|transient_local][,depth=N]` -> QosProfile."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    reliability, durability, depth = "reliable", "volatile", 10
    for p in parts:
        if p in ("reliable", "best_effort"):
            reliability = p
        elif p in ("volatile", "transient_local"):
            durability = p
        elif p.startswith("depth="):
            try:
                depth = int(p[6:])
            except ValueError:
                raise ValueError(f"QoS {text!r}: depth must be an integer") from None
        else:
            raise ValueError(
                f"QoS {text!r}: {p!r} is not reliable, best_effort, volatile, "
                "transient_local or depth=N"
            )
    return QosProfile(reliability, durability, depth)  # type: ignore[arg-type]
