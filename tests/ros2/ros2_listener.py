"""An independent ROS 2 participant (run as its own process): it knows nothing of irloc's
code, only topic names and ROS 2's message definitions. It discovers the writers on the
domain, takes each topic's type from the writer (DDS XTypes type lookup), reads the raw
CDR samples and decodes them with `rosbags`' ROS 2 definitions; it can publish an
/initialpose at a given time the same way (serialized by rosbags).

    python tests/ros2/ros2_listener.py --domain 42 --seconds 20 --out seen.json \
        --topic /tf --topic /r1/irloc/pose ... [--initialpose /r1/initialpose@8:x,y,yaw \
        [--linger 12]]

Output (JSON): {"types": {topic: DDS type name}, "messages": {topic: [decoded, ...]}}.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

from cyclonedds._clayer import ddspy_take
from cyclonedds.builtin import (
    BuiltinDataReader,
    BuiltinTopicDcpsPublication,
    BuiltinTopicDcpsSubscription,
)
from cyclonedds.core import InstanceState, SampleState, ViewState
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.dynamic import get_types_for_typeid
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from rosbags.typesys import Stores, get_typestore

LOOPBACK = """<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface name="lo"/>
</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto
</ParticipantIndex><MaxAutoParticipantIndex>60</MaxAutoParticipantIndex><Peers><Peer
address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>"""
STORE = get_typestore(Stores.ROS2_JAZZY)
ANY = SampleState.Any | ViewState.Any | InstanceState.Any


def ros_type(dds_type: str) -> str:
    """`pkg::msg::dds_::Type_` -> `pkg/msg/Type` (ROS 2's naming rule, inverted)."""
    pkg, kind, _, name = dds_type.split("::")
    return f"{pkg}/{kind}/{name[:-1]}"


def yaw(q: Any) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def t_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def summary(rtype: str, m: Any) -> Any:
    if rtype == "tf2_msgs/msg/TFMessage":
        return [
            {"parent": tf.header.frame_id, "child": tf.child_frame_id, "t": t_ns(tf.header.stamp),
             "x": tf.transform.translation.x, "y": tf.transform.translation.y,
             "yaw": yaw(tf.transform.rotation)}
            for tf in m.transforms
        ]  # fmt: skip
    if rtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        p = m.pose.pose
        return {"frame": m.header.frame_id, "t": t_ns(m.header.stamp), "x": p.position.x,
                "y": p.position.y, "yaw": yaw(p.orientation),
                "cov": [float(v) for v in m.pose.covariance]}  # fmt: skip
    if rtype == "nav_msgs/msg/Odometry":
        p = m.pose.pose
        return {"frame": m.header.frame_id, "child": m.child_frame_id, "t": t_ns(m.header.stamp),
                "x": p.position.x, "y": p.position.y, "yaw": yaw(p.orientation)}  # fmt: skip
    if rtype == "diagnostic_msgs/msg/DiagnosticArray":
        return [{"level": int(s.level), "name": s.name, "message": s.message,
                 "hardware_id": s.hardware_id, "values": {kv.key: kv.value for kv in s.values}}
                for s in m.status]  # fmt: skip
    if rtype == "visualization_msgs/msg/MarkerArray":
        return [{"ns": mk.ns, "id": int(mk.id), "type": int(mk.type), "action": int(mk.action),
                 "frame": mk.header.frame_id, "x": mk.pose.position.x, "y": mk.pose.position.y,
                 "z": mk.pose.position.z, "text": mk.text} for mk in m.markers]  # fmt: skip
    return {"type": rtype}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--topic", action="append", default=[])
    ap.add_argument(
        "--initialpose", action="append", default=[],
        help="TOPIC@WHEN:x,y,yaw, or TOPIC@WHEN:truth+dx,dy,dyaw (the latest pose on "
        "--truth-topic moved by dx, dy, dyaw: an operator clicking where the robot is); WHEN: "
        "seconds after the start, or `lost[,SECONDS]` (when /diagnostics first says mode lost, "
        "or at SECONDS at the latest); the start is the first message on --truth-topic (the "
        "robot's, whatever its process took to start), else the listener's",
    )  # fmt: skip
    ap.add_argument("--truth-topic", help="nav_msgs/Odometry of the true pose")
    ap.add_argument(
        "--linger", type=float, default=math.inf,
        help="stop this many seconds after the last --initialpose was sent (at --seconds at "
        "the latest)",
    )  # fmt: skip
    args = ap.parse_args()
    _domain = Domain(args.domain, LOOPBACK)
    dp = DomainParticipant(args.domain)
    pubs = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    subs = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)
    wanted = {"rt" + t: t for t in args.topic}
    plans = []
    for spec in args.initialpose:
        topic, _, rest = spec.partition("@")
        at, _, pose = rest.partition(":")
        relative = pose.startswith("truth+")
        values = [float(v) for v in pose.removeprefix("truth+").split(",")]
        # `lost` or `lost,SECONDS`: when /diagnostics first says lost, or at SECONDS at the latest
        when, _, latest = at.partition(",")
        deadline = (float(latest) if latest else math.inf) if when == "lost" else float(when)
        plans.append(("rt" + topic, deadline, values, relative))
    readers: dict[str, tuple[DataReader[Any], str]] = {}
    writers: dict[str, tuple[DataWriter[Any], Any]] = {}
    types: dict[str, str] = {}
    seen: dict[str, list[Any]] = {t: [] for t in args.topic}
    sent: list[dict[str, Any]] = []
    start = time.monotonic()
    robot_start: float | None = None
    end = start + args.seconds
    while time.monotonic() < end:
        for s in pubs.take(N=100):
            name = getattr(s, "topic_name", None)
            if name in wanted and name not in readers and s.type_id is not None:
                dtype, _ = get_types_for_typeid(dp, s.type_id, 5_000_000_000)
                types[wanted[name]] = s.type_name
                latched = s.qos[Policy.Durability] == Policy.Durability.TransientLocal
                qos = Qos(
                    Policy.Reliability.Reliable(0) if latched else Policy.Reliability.BestEffort,
                    Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile,
                    Policy.History.KeepLast(1000),
                )
                readers[name] = (
                    DataReader(dp, Topic(dp, name, dtype), qos=qos),
                    ros_type(s.type_name),
                )
        for s in subs.take(N=100):
            name = getattr(s, "topic_name", None)
            if any(p[0] == name for p in plans) and name not in writers and s.type_id is not None:
                dtype, _ = get_types_for_typeid(dp, s.type_id, 5_000_000_000)
                writers[name] = (DataWriter(dp, Topic(dp, name, dtype)), dtype)
                types[name[2:]] = s.type_name
        for name, (reader, rtype) in readers.items():
            for data, info in ddspy_take(reader._ref, ANY, 1000):
                if info.valid_data:
                    msg = STORE.deserialize_cdr(bytes(data), rtype)
                    seen[wanted[name]].append(summary(rtype, msg))
        if args.truth_topic and seen.get(args.truth_topic) and robot_start is None:
            robot_start = time.monotonic()
        if args.truth_topic and robot_start is None:
            time.sleep(0.02)
            continue  # the robot has not started: nothing is due
        elapsed = time.monotonic() - (start if robot_start is None else robot_start)
        for plan in list(plans):
            topic, at, (x, y, th), relative = plan
            if relative:
                truth = seen.get(args.truth_topic or "", [])
                if not truth:
                    continue
                x, y, th = truth[-1]["x"] + x, truth[-1]["y"] + y, truth[-1]["yaw"] + th
            lost = any(
                st["values"].get("mode") == "lost"
                for msg in seen.get("/diagnostics", [])[-5:]
                for st in msg
            )
            if (elapsed >= at or lost) and topic in writers:
                writer, dtype = writers[topic]
                rtype = ros_type(types[topic[2:]])
                msg = initialpose(rtype, x, y, th)
                writer.write(dtype.deserialize(bytes(STORE.serialize_cdr(msg, rtype))))
                sent.append({
                    "topic": topic[2:], "t": time.time_ns(), "x": x, "y": y, "yaw": th,
                    "when_lost": lost,
                })  # fmt: skip
                plans.remove(plan)
                if not plans:
                    end = min(end, time.monotonic() + args.linger)
        time.sleep(0.02)
    with open(args.out, "w", encoding="utf-8") as f:
        json.dump({"types": types, "messages": seen, "sent": sent}, f)


def initialpose(rtype: str, x: float, y: float, th: float) -> Any:
    T = STORE.types
    now = time.time_ns()
    import numpy as np

    cov = np.zeros(36)
    cov[0] = cov[7] = 0.25
    cov[35] = 0.07
    return T[rtype](
        header=T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=now // 10**9, nanosec=now % 10**9),
            frame_id="map",
        ),
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                orientation=T["geometry_msgs/msg/Quaternion"](
                    x=0.0, y=0.0, z=math.sin(th / 2), w=math.cos(th / 2)
                ),
            ),
            covariance=cov,
        ),
    )


if __name__ == "__main__":
    main()
