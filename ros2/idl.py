"""ROS 2 message types as cyclonedds IDL structs, generated from ROS 2's own message
definitions (the `rosbags` typestore, ROS 2 Jazzy), not written by hand.

ROS 2's DDS middlewares (rmw_cyclonedds_cpp, rmw_fastrtps_cpp) name the DDS type of
`pkg/msg/Type` `pkg::msg::dds_::Type_` and lay out its fields exactly as the `.msg` file,
nested types by the same rule, in plain CDR (XCDR1, final extensibility); the ROS topic
`/name` is the DDS topic `rt/name`. A struct with no field (`std_msgs/msg/Empty`) gets the
one placeholder byte ROS's IDL generator adds.

    Pose = message_class("geometry_msgs/msg/PoseWithCovarianceStamped")
    Pose.__idl_typename__ == "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"

`uint8[]`/`byte[]`/`char[]` fields (image data) hold `bytes`: the same wire format as a
sequence of octets, without a Python int per byte.
"""

from __future__ import annotations

import functools
from typing import Any

from cyclonedds.idl import IdlStruct, make_idl_struct
from cyclonedds.idl import types as idl_types
from cyclonedds.idl._machinery import BytesMachine
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

_BASE: dict[str, Any] = {
    "bool": bool,
    "byte": idl_types.byte,
    "char": idl_types.uint8,
    "int8": idl_types.int8,
    "uint8": idl_types.uint8,
    "int16": idl_types.int16,
    "uint16": idl_types.uint16,
    "int32": idl_types.int32,
    "uint32": idl_types.uint32,
    "int64": idl_types.int64,
    "uint64": idl_types.uint64,
    "float32": idl_types.float32,
    "float64": idl_types.float64,
    "string": str,
    "wstring": str,
}
_OCTETS = ("uint8", "byte", "char")
EMPTY_FIELD = "structure_needs_at_least_one_member"
"""The placeholder field of a message without fields, as rosidl_generator_dds_idl names it."""


@functools.cache
def typestore() -> Typestore:
    """ROS 2 Jazzy's message definitions, as `rosbags` ships them."""
    return get_typestore(Stores.ROS2_JAZZY)


def dds_type_name(ros_type: str) -> str:
    """`pkg/msg/Type` -> `pkg::msg::dds_::Type_` (ROS 2's DDS type name)."""
    pkg, kind, name = _split(ros_type)
    return f"{pkg}::{kind}::dds_::{name}_"


def dds_topic_name(topic: str) -> str:
    """ROS topic `/a/b` (or `a/b`) -> DDS topic `rt/a/b`.

    Raises:
        ValueError: an empty or malformed topic name.
    """
    name = topic.strip("/")
    if not name or "//" in name or any(c.isspace() for c in name):
        raise ValueError(f"ROS topic name {topic!r} is not valid")
    return f"rt/{name}"


def _split(ros_type: str) -> tuple[str, str, str]:
    parts = ros_type.split("/")
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"ROS type {ros_type!r} is not of the form pkg/msg/Type")
    return parts[0], parts[1], parts[2]


@functools.cache
def message_class(ros_type: str) -> type[IdlStruct]:
    """The cyclonedds struct of ROS 2 message `ros_type` (cached; nested types too).

    Raises:
        KeyError: a type `rosbags` does not define.
    """
    store = typestore()
    if ros_type not in store.fielddefs:
        raise KeyError(f"ROS type {ros_type!r} is not in ROS 2 Jazzy's definitions")
    _, fields = store.fielddefs[ros_type]
    annotations: dict[str, Any] = {name: _annotation(desc) for name, desc in fields}
    if not annotations:
        annotations = {EMPTY_FIELD: idl_types.uint8}
    _, _, name = _split(ros_type)
    cls = make_idl_struct(f"{name}_", dds_type_name(ros_type), annotations)
    _octet_fields_as_bytes(cls, [n for n, d in fields if _is_octet_sequence(d)])
    return cls


def _annotation(desc: Any) -> Any:
    kind, arg = desc[0].name, desc[1]
    if kind == "BASE":
        base, bound = arg
        if base in ("string", "wstring") and bound:
            return idl_types.bounded_str[bound]  # type: ignore[misc]
        return _BASE[base]
    if kind == "NAME":
        return message_class(arg)
    inner, size = arg
    if kind == "ARRAY":
        return idl_types.array[_annotation(inner), size]  # type: ignore[misc]
    if size:
        return idl_types.sequence[_annotation(inner), size]  # type: ignore[misc]
    return idl_types.sequence[_annotation(inner)]  # type: ignore[misc]


def _is_octet_sequence(desc: Any) -> bool:
    if desc[0].name != "SEQUENCE":
        return False
    inner, bound = desc[1]
    return bool(inner[0].name == "BASE" and inner[1][0] in _OCTETS and not bound)


def _octet_fields_as_bytes(cls: type[IdlStruct], names: list[str]) -> None:
    """Serialize octet sequences from and to `bytes` (the type object keeps sequence<uint8>)."""
    if not names:
        return
    idl: Any = cls.__idl__
    idl.populate()
    for machine in (idl.v1_machine, idl.v2_machine):
        for n in names:
            machine.members_machines[n] = BytesMachine()  # type: ignore[no-untyped-call]
