"""Building ROS 2 messages with `rosbags`' typestore (ROS 2 Jazzy types, CDR), no ROS needed.

`RosMessages.make(typename, **fields)` builds any message, the fields not given set to ROS's
defaults (zero, empty string, empty sequence, nested defaults), so that the exporter states
only what it means.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

_NUMPY = {
    "bool": np.bool_,
    "int8": np.int8,
    "uint8": np.uint8,
    "byte": np.uint8,
    "char": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


class RosMessages:
    """Message construction and CDR serialization for one typestore."""

    def __init__(self, store: Stores = Stores.ROS2_JAZZY) -> None:
        self.typestore: Typestore = get_typestore(store)

    def make(self, typename: str, **fields: Any) -> Any:
        """A message of `typename` with `fields`, every other field at its default.

        Raises:
            KeyError: an unknown type or field name.
        """
        _, defs = self.typestore.fielddefs[typename]
        names = {name for name, _ in defs}
        unknown = set(fields) - names
        if unknown:
            raise KeyError(f"{typename} has no field(s) {sorted(unknown)}")
        values = {}
        for name, desc in defs:
            values[name] = fields[name] if name in fields else self._default(desc)
            if name in fields and desc[0].name in ("ARRAY", "SEQUENCE"):
                values[name] = self._array(desc, fields[name])
        return self.typestore.types[typename](**values)

    def _array(self, desc: Any, value: Any) -> Any:
        inner = desc[1][0]
        if inner[0].name == "BASE" and inner[1][0] in _NUMPY:
            return np.asarray(value, dtype=_NUMPY[inner[1][0]])
        return list(value)

    def _default(self, desc: Any) -> Any:
        kind = desc[0].name
        if kind == "BASE":
            base = desc[1][0]
            return "" if base in ("string", "wstring") else (False if base == "bool" else 0)
        if kind == "NAME":
            return self.make(desc[1])
        inner, size = desc[1]
        if inner[0].name == "BASE" and inner[1][0] in _NUMPY:
            return np.zeros(size if kind == "ARRAY" else 0, dtype=_NUMPY[inner[1][0]])
        return [self._default(inner) for _ in range(size if kind == "ARRAY" else 0)]

    def serialize(self, message: Any, typename: str) -> bytes:
        """CDR bytes (little endian), as rosbag2 stores them."""
        return bytes(self.typestore.serialize_cdr(message, typename))

    def time(self, t_ns: int) -> Any:
        """builtin_interfaces/msg/Time of `t_ns`."""
        return self.make(
            "builtin_interfaces/msg/Time", sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000
        )

    def header(self, t_ns: int, frame_id: str) -> Any:
        """std_msgs/msg/Header."""
        return self.make("std_msgs/msg/Header", stamp=self.time(t_ns), frame_id=frame_id)

    def pose(self, x: float, y: float, z: float, q: tuple[float, ...]) -> Any:
        """geometry_msgs/msg/Pose from a position and a quaternion (x, y, z, w)."""
        return self.make(
            "geometry_msgs/msg/Pose",
            position=self.make("geometry_msgs/msg/Point", x=x, y=y, z=z),
            orientation=self.make("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]),
        )

    def color(self, rgba: tuple[float, float, float, float]) -> Any:
        """std_msgs/msg/ColorRGBA."""
        return self.make("std_msgs/msg/ColorRGBA", r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
