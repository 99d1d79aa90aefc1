"""The `foxglove` profile: one MCAP file with Foxglove's own schemas (protobuf), written by the
Foxglove SDK (`foxglove-sdk`), which Foxglove and Lichtblick open as it is.

Topics and frames: `export.topics`. The image panel shows `/cam0/image/compressed` with
`/cam0/camera_info` and the `/cam0/annotations` overlay (detected spots cyan, the landmarks
the localizer used green with their IDs); the 3D panel shows the transform tree (`/tf`,
`/tf_static`), the landmarks coloured by LED state (`/landmarks`), the pose (`/irloc/pose`)
with its 2-sigma ellipse (`/irloc/uncertainty`), and the ground truth when present.
"""

from __future__ import annotations

import math
from pathlib import Path

import foxglove
import numpy as np
from foxglove import channels as ch
from foxglove import messages as fm

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
)
from localizer.camera import CameraModel
from localizer.events import LedsChanged, PoseEstimate

FOXGLOVE_DISTORTION = {"radial-tangential": "plumb_bob", "equidistant": "kannala_brandt"}


def _ts(t_ns: int) -> fm.Timestamp:
    return fm.Timestamp(t_ns // 1_000_000_000, t_ns % 1_000_000_000)


def _color(rgba: tuple[float, float, float, float]) -> fm.Color:
    return fm.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def _pose(p: Pose2, z: float = 0.0) -> fm.Pose:
    qx, qy, qz, qw = quaternion_from_yaw(p[2])
    return fm.Pose(
        position=fm.Vector3(x=p[0], y=p[1], z=z), orientation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw)
    )


def _transform(t_ns: int, parent: str, child: str, p: Pose2) -> fm.FrameTransform:
    qx, qy, qz, qw = quaternion_from_yaw(p[2])
    return fm.FrameTransform(
        timestamp=_ts(t_ns),
        parent_frame_id=parent,
        child_frame_id=child,
        translation=fm.Vector3(x=p[0], y=p[1], z=0.0),
        rotation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw),
    )


def camera_calibration(camera: CameraModel, t_ns: int) -> fm.CameraCalibration:
    """Foxglove's CameraCalibration of the lens (K, P = [K | 0], R = I, D as OpenCV's)."""
    K = [camera.fu, 0.0, camera.cu, 0.0, camera.fv, camera.cv, 0.0, 0.0, 1.0]
    return fm.CameraCalibration(
        timestamp=_ts(t_ns),
        frame_id=CAMERA,
        width=camera.width,
        height=camera.height,
        distortion_model=FOXGLOVE_DISTORTION[camera.distortion_model],
        D=[float(d) for d in camera.distortion],
        K=K,
        R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        P=[K[0], 0.0, K[2], 0.0, 0.0, K[4], K[5], 0.0, 0.0, 0.0, 1.0, 0.0],
    )


def image_annotations(frame: FrameContent) -> fm.ImageAnnotations:
    """Spots (cyan circles) and used landmarks (green circles with their IDs)."""
    ts = _ts(frame.t_ns)
    circles = [
        fm.CircleAnnotation(
            timestamp=ts,
            position=fm.Point2(x=float(u), y=float(v)),
            diameter=10.0,
            thickness=1.5,
            outline_color=_color(SPOT_RGBA),
            fill_color=_color((0.0, 0.0, 0.0, 0.0)),
        )
        for u, v in frame.spots
    ]
    texts = []
    for lid, (u, v) in frame.landmark_pixels.items():
        circles.append(
            fm.CircleAnnotation(
                timestamp=ts,
                position=fm.Point2(x=u, y=v),
                diameter=18.0,
                thickness=2.0,
                outline_color=_color(USED_RGBA),
                fill_color=_color((0.0, 0.0, 0.0, 0.0)),
            )
        )
        texts.append(
            fm.TextAnnotation(
                timestamp=ts,
                position=fm.Point2(x=u + 12, y=v - 12),
                text=str(lid),
                font_size=14.0,
                text_color=_color(USED_RGBA),
                background_color=_color((0.0, 0.0, 0.0, 0.6)),
            )
        )
    return fm.ImageAnnotations(circles=circles, texts=texts)


def landmark_scene(content: ExportContent, t_ns: int) -> fm.SceneUpdate:
    """Every landmark as a sphere coloured by its LED state at `t_ns`, with its ID."""
    lm = content.recording.landmark_map
    ids = [int(i) for i in lm.ids]
    lit = lit_at(content.leds, ids, t_ns)
    entities = []
    d = LANDMARK_DIAMETER_M
    for i, p in zip(ids, lm.positions, strict=True):
        pose = fm.Pose(
            position=fm.Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
            orientation=fm.Quaternion(w=1.0),
        )
        label = fm.Pose(
            position=fm.Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2]) - 0.12),
            orientation=fm.Quaternion(w=1.0),
        )
        colour = _color(LIT_RGBA if i in lit else DARK_RGBA)
        entities.append(
            fm.SceneEntity(
                timestamp=_ts(t_ns),
                frame_id=MAP,
                id=f"landmark/{i}",
                metadata=[fm.KeyValuePair(key="led", value="lit" if i in lit else "dark")],
                spheres=[
                    fm.SpherePrimitive(pose=pose, size=fm.Vector3(x=d, y=d, z=d), color=colour)
                ],
                texts=[
                    fm.TextPrimitive(
                        pose=label,
                        billboard=True,
                        font_size=14.0,
                        scale_invariant=True,
                        color=colour,
                        text=str(i),
                    )
                ],
            )
        )
    return fm.SceneUpdate(entities=entities)


def uncertainty(est: PoseEstimate) -> fm.SceneUpdate:
    """The 2-sigma ellipse of the position as a flat elliptic cylinder on the floor."""
    vals, vecs = np.linalg.eigh(np.asarray(est.covariance)[:2, :2])
    vals = np.clip(vals, 1e-12, None)
    angle = math.atan2(float(vecs[1, 1]), float(vecs[0, 1]))  # the major axis
    size = fm.Vector3(x=4 * math.sqrt(vals[1]), y=4 * math.sqrt(vals[0]), z=0.002)
    return fm.SceneUpdate(
        entities=[
            fm.SceneEntity(
                timestamp=_ts(est.t_ns),
                frame_id=MAP,
                id="uncertainty",
                cylinders=[
                    fm.CylinderPrimitive(
                        pose=_pose((est.x, est.y, angle), 0.001),
                        size=size,
                        bottom_scale=1.0,
                        top_scale=1.0,
                        color=_color((0.2, 0.6, 1.0, 0.35)),
                    )
                ],
            )
        ]
    )


def write_foxglove(content: ExportContent, out: Path) -> dict[str, int]:
    """Write the export; returns the message count per topic."""
    ctx = foxglove.Context()
    writer = foxglove.open_mcap(str(out), allow_overwrite=True, context=ctx)
    counts: dict[str, int] = {}
    try:
        _write(content, ctx, counts)
    finally:
        writer.close()
    return counts


def _write(content: ExportContent, ctx: foxglove.Context, counts: dict[str, int]) -> None:
    image = ch.CompressedImageChannel("/cam0/image/compressed", context=ctx)
    info = ch.CameraCalibrationChannel("/cam0/camera_info", context=ctx)
    marks = ch.ImageAnnotationsChannel("/cam0/annotations", context=ctx)
    pose = ch.PoseInFrameChannel("/irloc/pose", context=ctx)
    pose_cov = ch.OdometryChannel("/irloc/pose_with_covariance", context=ctx)
    ellipse = ch.SceneUpdateChannel("/irloc/uncertainty", context=ctx)
    mode = ch.LogChannel("/irloc/mode", context=ctx)
    tf = ch.FrameTransformsChannel("/tf", context=ctx)
    tf_static = ch.FrameTransformsChannel("/tf_static", context=ctx)
    odom = ch.OdometryChannel("/odom", context=ctx)
    scene = ch.SceneUpdateChannel("/landmarks", context=ctx)
    truth = ch.PoseInFrameChannel("/groundtruth", context=ctx) if content.groundtruth else None

    def log(channel: object, topic: str, msg: object, t_ns: int) -> None:
        channel.log(msg, log_time=t_ns)  # type: ignore[attr-defined]
        counts[topic] = counts.get(topic, 0) + 1

    t0 = content.start_ns
    xyz, q = body_camera(content.camera)
    log(
        tf_static,
        "/tf_static",
        fm.FrameTransforms(
            transforms=[
                fm.FrameTransform(
                    timestamp=_ts(t0),
                    parent_frame_id=BASE,
                    child_frame_id=CAMERA,
                    translation=fm.Vector3(x=xyz[0], y=xyz[1], z=xyz[2]),
                    rotation=fm.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
                )
            ]
        ),
        t0,
    )
    log(scene, "/landmarks", landmark_scene(content, t0), t0)
    last_mode = None
    for item in content.timeline():
        if isinstance(item, OdometrySample):
            v, w = item.twist
            log(
                odom,
                "/odom",
                fm.Odometry(
                    timestamp=_ts(item.t_ns),
                    frame_id=ODOM,
                    body_frame_id=BASE,
                    pose=_pose(item.pose),
                    linear_velocity=fm.Vector3(x=v),
                    angular_velocity=fm.Vector3(z=w),
                ),
                item.t_ns,
            )
            continue
        if isinstance(item, LedsChanged):
            log(scene, "/landmarks", landmark_scene(content, item.t_ns), item.t_ns)
            continue
        if isinstance(item, TruthPose):
            if truth is not None:
                log(
                    truth,
                    "/groundtruth",
                    fm.PoseInFrame(timestamp=_ts(item.t_ns), frame_id=MAP, pose=_pose(item.pose)),
                    item.t_ns,
                )
            continue
        frame, t = item, item.t_ns
        if frame.png_path is not None:
            data = frame.png_path.read_bytes()
            log(
                image,
                "/cam0/image/compressed",
                fm.CompressedImage(timestamp=_ts(t), frame_id=CAMERA, data=data, format="png"),
                t,
            )
            log(info, "/cam0/camera_info", camera_calibration(content.camera, t), t)
            log(marks, "/cam0/annotations", image_annotations(frame), t)
        transforms = [_transform(t, ODOM, BASE, frame.odom_pose)]
        est = frame.estimate
        if frame.map_odom is not None:
            transforms.insert(0, _transform(t, MAP, ODOM, frame.map_odom))
        log(tf, "/tf", fm.FrameTransforms(transforms=transforms), t)
        if isinstance(est, PoseEstimate):
            p_est = (est.x, est.y, est.theta)
            log(
                pose,
                "/irloc/pose",
                fm.PoseInFrame(timestamp=_ts(t), frame_id=MAP, pose=_pose(p_est)),
                t,
            )
            log(
                pose_cov,
                "/irloc/pose_with_covariance",
                fm.Odometry(
                    timestamp=_ts(t),
                    frame_id=MAP,
                    body_frame_id=BASE,
                    pose=_pose(p_est),
                    pose_covariance=covariance6(est),
                ),
                t,
            )
            log(ellipse, "/irloc/uncertainty", uncertainty(est), t)
        if est.mode != last_mode:
            text = f"mode: {est.mode}"
            log(
                mode,
                "/irloc/mode",
                fm.Log(timestamp=_ts(t), level=fm.LogLevel.Info, message=text, name="irloc"),
                t,
            )
            last_mode = est.mode
