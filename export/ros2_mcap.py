"""The `ros2` profile: a rosbag2 in MCAP storage with standard ROS 2 messages in CDR, written
by `rosbags` (no ROS installed), which `ros2 bag play`, Nav2's tools, RViz and Foxglove read.

The bag is written as one `.mcap` file (rosbag2's MCAP storage keeps its metadata inside the
file; `ros2 bag play OUT.mcap` opens it) or, when OUT does not end in `.mcap`, as the usual
rosbag2 folder (`OUT/metadata.yaml` and `OUT/OUT.mcap`). Topics and frames: `export.topics`.
`/tf_static` is offered transient-local (latched), as `robot_state_publisher` offers it.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer

from export.content import (
    ExportContent,
    FrameContent,
    OdometrySample,
    Pose2,
    TruthPose,
    body_camera,
    covariance6,
    lit_at,
    quaternion_from_yaw,
)
from export.ros2_messages import RosMessages
from export.topics import (
    BASE,
    CAMERA,
    DARK_RGBA,
    LANDMARK_DIAMETER_M,
    LIT_RGBA,
    MAP,
    ODOM,
    SPOT_RGBA,
    USED_RGBA,
    topics,
)
from localizer.camera import CameraModel
from localizer.events import LedsChanged, PoseEstimate

ROS_DISTORTION = {"radial-tangential": "plumb_bob", "equidistant": "equidistant"}
ROS_IMAGE_FORMAT = "mono8; png compressed"
"""CompressedImage.format as image_transport's compressed plugin writes it for 8-bit PNGs."""
_NEVER = QosTime(sec=0x7FFFFFFF, nsec=0xFFFFFFFF)  # rosbag2's "infinite" duration
LATCHED = Qos(
    history=QosHistory.KEEP_LAST,
    depth=1,
    reliability=QosReliability.RELIABLE,
    durability=QosDurability.TRANSIENT_LOCAL,
    deadline=_NEVER,
    lifespan=_NEVER,
    liveliness=QosLiveliness.AUTOMATIC,
    liveliness_lease_duration=_NEVER,
    avoid_ros_namespace_conventions=False,
)


class _Bag:
    """One rosbag2 writer and its connections, counting messages per topic."""

    def __init__(self, writer: Writer, ros: RosMessages) -> None:
        self.writer, self.ros = writer, ros
        self.types = topics("ros2")
        self.connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    def write(self, topic: str, message: Any, t_ns: int) -> None:
        typename = self.types[topic]
        if topic not in self.connections:
            qos = [LATCHED] if topic == "/tf_static" else []
            self.connections[topic] = self.writer.add_connection(
                topic, typename, typestore=self.ros.typestore, offered_qos_profiles=qos
            )
        self.writer.write(self.connections[topic], t_ns, self.ros.serialize(message, typename))
        self.counts[topic] = self.counts.get(topic, 0) + 1


def camera_info(ros: RosMessages, camera: CameraModel, t_ns: int) -> Any:
    """sensor_msgs/msg/CameraInfo of the lens (K, P = [K | 0], R = I, D as OpenCV's)."""
    K = [camera.fu, 0.0, camera.cu, 0.0, camera.fv, camera.cv, 0.0, 0.0, 1.0]
    return ros.make(
        "sensor_msgs/msg/CameraInfo",
        header=ros.header(t_ns, CAMERA),
        height=camera.height,
        width=camera.width,
        distortion_model=ROS_DISTORTION[camera.distortion_model],
        d=[float(v) for v in camera.distortion],
        k=K,
        r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p=[K[0], 0.0, K[2], 0.0, 0.0, K[4], K[5], 0.0, 0.0, 0.0, 1.0, 0.0],
    )


def _transform(ros: RosMessages, t_ns: int, parent: str, child: str, p: Pose2) -> Any:
    q = quaternion_from_yaw(p[2])
    return ros.make(
        "geometry_msgs/msg/TransformStamped",
        header=ros.header(t_ns, parent),
        child_frame_id=child,
        transform=ros.make(
            "geometry_msgs/msg/Transform",
            translation=ros.make("geometry_msgs/msg/Vector3", x=p[0], y=p[1], z=0.0),
            rotation=ros.make("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


def image_markers(ros: RosMessages, frame: FrameContent) -> list[Any]:
    """visualization_msgs/msg/ImageMarker: one POINTS marker of the spots (ns `spots`), and a
    CIRCLE per landmark used (ns `landmarks`, id = the landmark's ID)."""
    header = ros.header(frame.t_ns, CAMERA)
    point = "geometry_msgs/msg/Point"
    out = [
        ros.make(
            "visualization_msgs/msg/ImageMarker",
            header=header,
            ns="spots",
            id=0,
            type=4,
            scale=6.0,
            outline_color=ros.color(SPOT_RGBA),
            points=[ros.make(point, x=float(u), y=float(v)) for u, v in frame.spots],
        )
    ]
    for lid, (u, v) in frame.landmark_pixels.items():
        out.append(
            ros.make(
                "visualization_msgs/msg/ImageMarker",
                header=header,
                ns="landmarks",
                id=lid,
                type=0,
                position=ros.make(point, x=u, y=v),
                scale=9.0,
                outline_color=ros.color(USED_RGBA),
            )
        )
    return out


def landmark_markers(ros: RosMessages, content: ExportContent, t_ns: int) -> Any:
    """visualization_msgs/msg/MarkerArray: a sphere per landmark coloured by its LED state
    (ns `landmarks`) and its ID as text (ns `landmark_ids`), id = the landmark's ID."""
    lm = content.recording.landmark_map
    ids = [int(i) for i in lm.ids]
    lit = lit_at(content.leds, ids, t_ns)
    d = LANDMARK_DIAMETER_M
    markers = []
    for i, p in zip(ids, lm.positions, strict=True):
        colour = ros.color(LIT_RGBA if i in lit else DARK_RGBA)
        header = ros.header(t_ns, MAP)
        x, y, z = (float(v) for v in p)
        markers.append(
            ros.make(
                "visualization_msgs/msg/Marker",
                header=header,
                ns="landmarks",
                id=i,
                type=2,
                pose=ros.pose(x, y, z, (0.0, 0.0, 0.0, 1.0)),
                scale=ros.make("geometry_msgs/msg/Vector3", x=d, y=d, z=d),
                color=colour,
            )
        )
        markers.append(
            ros.make(
                "visualization_msgs/msg/Marker",
                header=header,
                ns="landmark_ids",
                id=i,
                type=9,
                pose=ros.pose(x, y, z - 0.12, (0.0, 0.0, 0.0, 1.0)),
                scale=ros.make("geometry_msgs/msg/Vector3", z=0.1),
                color=colour,
                text=str(i),
            )
        )
    return ros.make("visualization_msgs/msg/MarkerArray", markers=markers)


def write_ros2(content: ExportContent, out: Path) -> dict[str, int]:
    """Write the export; returns the message count per topic."""
    ros = RosMessages()
    single = out.suffix == ".mcap"
    with tempfile.TemporaryDirectory(prefix=".irloc-export-", dir=out.parent) as tmp:
        root = Path(tmp) / (out.stem if single else out.name)
        writer = Writer(root, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        bag = _Bag(writer, ros)
        try:
            _write(content, bag)
        finally:
            writer.close()
        if single:
            Path(root / f"{root.name}.mcap").replace(out)
        else:
            if out.exists():
                shutil.rmtree(out)
            root.replace(out)
    return bag.counts


def _write(content: ExportContent, bag: _Bag) -> None:
    ros = bag.ros
    t0 = content.start_ns
    xyz, q = body_camera(content.camera)
    static = ros.make(
        "geometry_msgs/msg/TransformStamped",
        header=ros.header(t0, BASE),
        child_frame_id=CAMERA,
        transform=ros.make(
            "geometry_msgs/msg/Transform",
            translation=ros.make("geometry_msgs/msg/Vector3", x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=ros.make("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )
    bag.write("/tf_static", ros.make("tf2_msgs/msg/TFMessage", transforms=[static]), t0)
    info = camera_info(ros, content.camera, t0)
    bag.write("/landmarks", landmark_markers(ros, content, t0), t0)
    last_mode = None
    for item in content.timeline():
        if isinstance(item, OdometrySample):
            bag.write("/odom", _odometry(ros, item), item.t_ns)
            continue
        if isinstance(item, LedsChanged):
            bag.write("/landmarks", landmark_markers(ros, content, item.t_ns), item.t_ns)
            continue
        if isinstance(item, TruthPose):
            x, y, th = item.pose
            bag.write(
                "/groundtruth",
                ros.make(
                    "geometry_msgs/msg/PoseStamped",
                    header=ros.header(item.t_ns, MAP),
                    pose=ros.pose(x, y, 0.0, quaternion_from_yaw(th)),
                ),
                item.t_ns,
            )
            continue
        frame, t = item, item.t_ns
        if frame.png_path is not None:
            data = np.frombuffer(frame.png_path.read_bytes(), dtype=np.uint8)
            bag.write(
                "/cam0/image/compressed",
                ros.make(
                    "sensor_msgs/msg/CompressedImage",
                    header=ros.header(t, CAMERA),
                    format=ROS_IMAGE_FORMAT,
                    data=data,
                ),
                t,
            )
            info.header = ros.header(t, CAMERA)
            bag.write("/cam0/camera_info", info, t)
            for marker in image_markers(ros, frame):
                bag.write("/cam0/annotations", marker, t)
        transforms = [_transform(ros, t, ODOM, BASE, frame.odom_pose)]
        if frame.map_odom is not None:
            transforms.insert(0, _transform(ros, t, MAP, ODOM, frame.map_odom))
        bag.write("/tf", ros.make("tf2_msgs/msg/TFMessage", transforms=transforms), t)
        est = frame.estimate
        if isinstance(est, PoseEstimate):
            pose = ros.make(
                "geometry_msgs/msg/PoseWithCovariance",
                pose=ros.pose(est.x, est.y, 0.0, quaternion_from_yaw(est.theta)),
                covariance=covariance6(est),
            )
            bag.write(
                "/irloc/pose",
                ros.make(
                    "geometry_msgs/msg/PoseWithCovarianceStamped",
                    header=ros.header(t, MAP),
                    pose=pose,
                ),
                t,
            )
        if est.mode != last_mode:
            bag.write("/irloc/mode", ros.make("std_msgs/msg/String", data=est.mode), t)
            last_mode = est.mode


def _odometry(ros: RosMessages, sample: OdometrySample) -> Any:
    """nav_msgs/msg/Odometry of one sample (odom -> base_link, speeds in base_link)."""
    x, y, th = sample.pose
    v, w = sample.twist
    vec = "geometry_msgs/msg/Vector3"
    return ros.make(
        "nav_msgs/msg/Odometry",
        header=ros.header(sample.t_ns, ODOM),
        child_frame_id=BASE,
        pose=ros.make(
            "geometry_msgs/msg/PoseWithCovariance",
            pose=ros.pose(x, y, 0.0, quaternion_from_yaw(th)),
        ),
        twist=ros.make(
            "geometry_msgs/msg/TwistWithCovariance",
            twist=ros.make(
                "geometry_msgs/msg/Twist", linear=ros.make(vec, x=v), angular=ros.make(vec, z=w)
            ),
        ),
    )
