"""Building and reading ROS 2 messages (the generated structs of `ros2.idl`): `new` with
ROS's defaults for fields not given, stamps, quaternions, transforms, covariances.

Conventions: REP-103 (x forward, y left, z up, yaw CCW from +x, radians), REP-105 frames,
stamps as `builtin_interfaces/Time` (ROS time: Unix ns on the robot's clock).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from localizer.types import FloatArray
from ros2.idl import EMPTY_FIELD, message_class, typestore

NS = 1_000_000_000
Pose2 = tuple[float, float, float]
"""A planar pose (x, y, yaw): metres, metres, radians."""


def new(ros_type: str, **fields: Any) -> Any:
    """A message of `ros_type` with `fields`, every other field at ROS's default (zero,
    empty string, empty sequence, nested defaults, fixed arrays of zeros).

    Raises:
        KeyError: an unknown type or field name.
    """
    _, defs = typestore().fielddefs[ros_type]
    names = {n for n, _ in defs}
    unknown = set(fields) - names
    if unknown:
        raise KeyError(f"{ros_type} has no field(s) {sorted(unknown)}")
    values = {n: fields[n] if n in fields else _default(d) for n, d in defs}
    if not defs:
        values = {EMPTY_FIELD: 0}
    return message_class(ros_type)(**values)


def _default(desc: Any) -> Any:
    kind, arg = desc[0].name, desc[1]
    if kind == "BASE":
        base = arg[0]
        if base in ("string", "wstring"):
            return ""
        if base == "bool":
            return False
        return 0.0 if base.startswith("float") else 0
    if kind == "NAME":
        return new(arg)
    inner, size = arg
    if kind == "SEQUENCE":
        octets = inner[0].name == "BASE" and inner[1][0] in ("uint8", "byte", "char")
        return b"" if octets and not size else []
    return [_default(inner) for _ in range(size)]


def stamp(t_ns: int) -> Any:
    """builtin_interfaces/msg/Time of Unix ns `t_ns`."""
    return new("builtin_interfaces/msg/Time", sec=t_ns // NS, nanosec=t_ns % NS)


def stamp_ns(msg_stamp: Any) -> int:
    """Unix ns of a builtin_interfaces/msg/Time."""
    return int(msg_stamp.sec) * NS + int(msg_stamp.nanosec)


def header(t_ns: int, frame_id: str) -> Any:
    return new("std_msgs/msg/Header", stamp=stamp(t_ns), frame_id=frame_id)


def quaternion_from_yaw(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by `yaw` about +z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Yaw (rad, in (-pi, pi]) of a quaternion (its rotation about +z, ZYX convention)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def compose(a: Pose2, b: Pose2) -> Pose2:
    """a * b of planar transforms (T_x_z = T_x_y * T_y_z)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2]))


def inverse(a: Pose2) -> Pose2:
    """The inverse of a planar transform."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), s * a[0] - c * a[1], wrap(-a[2]))


def wrap(angle: float) -> float:
    """Angle in (-pi, pi]."""
    a = math.remainder(angle, 2.0 * math.pi)
    return math.pi if a == -math.pi else a


def pose_msg(p: Pose2, z: float = 0.0) -> Any:
    """geometry_msgs/msg/Pose of a planar pose."""
    q = quaternion_from_yaw(p[2])
    return new(
        "geometry_msgs/msg/Pose",
        position=new("geometry_msgs/msg/Point", x=p[0], y=p[1], z=z),
        orientation=new("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]),
    )


def twist_msg(v: float, w: float) -> Any:
    """geometry_msgs/msg/TwistWithCovariance of a planar motion: forward `v` m/s, turning `w`
    rad/s (covariance unknown: zeros)."""
    return new(
        "geometry_msgs/msg/TwistWithCovariance",
        twist=new(
            "geometry_msgs/msg/Twist",
            linear=new("geometry_msgs/msg/Vector3", x=v),
            angular=new("geometry_msgs/msg/Vector3", z=w),
        ),
    )


def pose2_of(pose: Any) -> Pose2:
    """The planar pose of a geometry_msgs/msg/Pose (or Transform: translation, rotation)."""
    p = pose.position if hasattr(pose, "position") else pose.translation
    q = pose.orientation if hasattr(pose, "orientation") else pose.rotation
    return (float(p.x), float(p.y), yaw_from_quaternion(q.x, q.y, q.z, q.w))


def transform_stamped(t_ns: int, parent: str, child: str, p: Pose2) -> Any:
    """geometry_msgs/msg/TransformStamped `parent` -> `child` (T_parent_child)."""
    q = quaternion_from_yaw(p[2])
    return new(
        "geometry_msgs/msg/TransformStamped",
        header=header(t_ns, parent),
        child_frame_id=child,
        transform=new(
            "geometry_msgs/msg/Transform",
            translation=new("geometry_msgs/msg/Vector3", x=p[0], y=p[1], z=0.0),
            rotation=new("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


FLAT_VARIANCE = 1e6
"""Variance put on the states a planar localizer does not estimate (z, roll, pitch): a
consumer that fuses them (robot_localization) ignores them."""


def covariance6(cov3: FloatArray) -> list[float]:
    """The 6x6 row-major covariance (x, y, z, rotX, rotY, rotZ) of a (3, 3) covariance of
    (x, y, yaw); z, roll and pitch get `FLAT_VARIANCE`."""
    c = np.zeros((6, 6))
    idx = [0, 1, 5]
    c[np.ix_(idx, idx)] = np.asarray(cov3, dtype=np.float64).reshape(3, 3)
    c[2, 2] = c[3, 3] = c[4, 4] = FLAT_VARIANCE
    return [float(v) for v in c.ravel()]


def covariance3(cov6: Any) -> FloatArray:
    """The (3, 3) covariance of (x, y, yaw) in a 6x6 row-major covariance."""
    c = np.asarray(cov6, dtype=np.float64).reshape(6, 6)
    idx = [0, 1, 5]
    return np.asarray(c[np.ix_(idx, idx)], dtype=np.float64)
