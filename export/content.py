"""What an export holds, independent of the message schemas: the localizer run over a
recording, frame by frame, with the frames (REP-105) and the odometry it implies.

Per listed frame: the PNG as recorded, the spots `localizer.spots.detect_spots` finds in it,
the localizer's estimate, the pixel where each landmark it used is predicted from that
estimate, and `map -> odom`. The odometry frame is the wheel odometry integrated from the
first sample (eqs. 5-6, each sample's speeds over the interval up to it, as the recording
contract says); `map -> odom` is then `T_map_base (the estimate) * inv(T_odom_base (the
odometry at the frame's time))`, which Nav2 takes from a positioning source (REP-105).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, predict_pixels
from localizer.events import LedsChanged, NoPose, PoseEstimate
from localizer.geometry import (
    T_world_body_from_pose,
    invert_transform,
    pose_from_T_world_body,
    wrap_angle,
)
from localizer.odometry import integrate_odometry
from localizer.spots import DetectionConfig, detect_spots
from localizer.types import FloatArray, IntArray
from recording.layout import GROUNDTRUTH_FILE
from recording.localize import PoseSource, localized
from recording.reader import Recording, read_groundtruth

Pose2 = tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class FrameContent:
    """One listed frame.

    Attributes:
        t_ns: the frame's time.
        png_path: the recorded PNG (written as is); None when missing or unreadable.
        spots: detected spot pixels, shape (N, 2).
        estimate: the localizer's output.
        landmark_pixels: landmark ID -> (u, v) predicted from the estimate, for the IDs used.
        odom_pose: the odometry pose (x, y, theta) at the frame's time, in `odom`.
        map_odom: `map -> odom` (x, y, theta), None without a pose.
        cpu_s: the localizer's CPU time for the frame, seconds.
    """

    t_ns: int
    png_path: Path | None
    spots: FloatArray
    estimate: PoseEstimate | NoPose
    landmark_pixels: dict[int, tuple[float, float]]
    odom_pose: Pose2
    map_odom: Pose2 | None
    cpu_s: float


@dataclass(frozen=True, eq=False)
class Odometry:
    """The wheel odometry integrated, per sample.

    Attributes:
        t_ns: sample times, shape (N,).
        pose: (x, y, theta) in `odom`, shape (N, 3).
        twist: (forward speed m/s, turn rate rad/s), shape (N, 2).
    """

    t_ns: IntArray
    pose: FloatArray
    twist: FloatArray

    def at(self, t_ns: int) -> Pose2:
        """The pose at `t_ns` (interpolated between samples; the first before the start)."""
        if len(self.t_ns) == 0:
            return (0.0, 0.0, 0.0)
        k = int(np.searchsorted(self.t_ns, t_ns, side="right"))
        if k == 0:
            return (0.0, 0.0, 0.0)
        if k == len(self.t_ns):
            x, y, th = self.pose[-1]
            return (float(x), float(y), float(th))
        t0, t1 = self.t_ns[k - 1], self.t_ns[k]
        a = (t_ns - t0) / max(t1 - t0, 1)
        p0, p1 = self.pose[k - 1], self.pose[k]
        th = p0[2] + a * float(wrap_angle(p1[2] - p0[2]))
        return (
            float(p0[0] + a * (p1[0] - p0[0])),
            float(p0[1] + a * (p1[1] - p0[1])),
            float(wrap_angle(th)),
        )


def integrate_wheel_odometry(rec: Recording) -> Odometry:
    """Dead reckoning from the recording's wheel speeds, from (0, 0, 0) at the first sample."""
    t = rec.odom_t_ns
    n = len(t)
    pose = np.zeros((n, 3))
    twist = np.zeros((n, 2))
    W = rec.robot.wheel_base
    x = y = th = 0.0
    for k in range(n):
        vl, vr = float(rec.odom_v[k, 0]), float(rec.odom_v[k, 1])
        if k > 0:
            x, y, th = integrate_odometry(x, y, th, vl, vr, (t[k] - t[k - 1]) * 1e-9, W)
        pose[k] = (x, y, th)
        twist[k] = (0.5 * (vl + vr), (vr - vl) / W)
    return Odometry(t.astype(np.int64), pose, twist)


def compose(a: Pose2, b: Pose2) -> Pose2:
    """Planar `a * b` (b expressed in a's frame), through `localizer.geometry`'s transforms."""
    return pose_from_T_world_body(T_world_body_from_pose(*a) @ T_world_body_from_pose(*b))


def inverse(a: Pose2) -> Pose2:
    """Planar inverse."""
    return pose_from_T_world_body(invert_transform(T_world_body_from_pose(*a)))


@dataclass(frozen=True)
class OdometrySample:
    """One wheel-odometry sample integrated: pose in `odom`, (forward m/s, turn rad/s)."""

    t_ns: int
    pose: Pose2
    twist: tuple[float, float]


@dataclass(frozen=True)
class TruthPose:
    """One ground-truth pose (x, y, theta) in `map`."""

    t_ns: int
    pose: Pose2


TimelineItem = OdometrySample | LedsChanged | TruthPose | FrameContent


@dataclass(frozen=True, eq=False)
class ExportContent:
    """Everything an export writes, schema-free.

    Attributes:
        recording: the recording (static files, LED states).
        odometry: the integrated wheel odometry.
        groundtruth: (t_ns (N,), poses (N, 3)) or None.
        frames: an iterator over the frames, localizing as it goes (once).
    """

    recording: Recording
    odometry: Odometry
    groundtruth: tuple[IntArray, FloatArray] | None
    frames: Iterator[FrameContent]

    @property
    def camera(self) -> CameraModel:
        return self.recording.camera

    @property
    def leds(self) -> list[LedsChanged]:
        return self.recording.leds

    @property
    def start_ns(self) -> int:
        """The first frame's or odometry sample's time (0 when there is neither)."""
        rec = self.recording
        first = [f.t_ns for f in rec.frames[:1]] + [int(t) for t in rec.odom_t_ns[:1]]
        return int(min(first)) if first else 0

    def timeline(self) -> Iterator[TimelineItem]:
        """Odometry samples, LED changes after the start, ground truth and frames, in time
        order (at equal times in that order: a frame comes after what happened at its time)."""
        odo = self.odometry
        start = self.start_ns
        leds = iter([e for e in self.leds if e.t_ns > start])
        truth = iter(self._truth())
        next_led, next_truth = next(leds, None), next(truth, None)
        k = 0
        for frame in self.frames:
            while k < len(odo.t_ns) and odo.t_ns[k] <= frame.t_ns:
                x, y, th = (float(v) for v in odo.pose[k])
                v, w = (float(v) for v in odo.twist[k])
                yield OdometrySample(int(odo.t_ns[k]), (x, y, th), (v, w))
                k += 1
            while next_led is not None and next_led.t_ns <= frame.t_ns:
                yield next_led
                next_led = next(leds, None)
            while next_truth is not None and next_truth.t_ns <= frame.t_ns:
                yield next_truth
                next_truth = next(truth, None)
            yield frame

    def _truth(self) -> list[TruthPose]:
        if self.groundtruth is None:
            return []
        t, poses = self.groundtruth
        return [
            TruthPose(int(t[k]), (float(poses[k, 0]), float(poses[k, 1]), float(poses[k, 2])))
            for k in range(len(t))
        ]


def export_content(
    rec: Recording,
    *,
    detection: DetectionConfig | None = None,
    poses: PoseSource | None = None,
) -> ExportContent:
    """The content of `rec` (frames localized lazily, while the writer iterates); `poses`:
    `replay` or `live` (`recording.localize.localized`; None: `live` when the recording has
    them)."""
    odometry = integrate_wheel_odometry(rec)
    truth = read_groundtruth(rec.root) if (rec.root / GROUNDTRUTH_FILE).is_file() else None
    return ExportContent(
        rec, odometry, truth, _frames(rec, odometry, detection or DetectionConfig(), poses)
    )


def _frames(
    rec: Recording, odometry: Odometry, cfg: DetectionConfig, poses: PoseSource | None
) -> Iterator[FrameContent]:
    lm = rec.landmark_map
    for done in localized(rec, poses):
        est = done.estimate
        spots = np.zeros((0, 2)) if done.image is None else detect_spots(done.image, cfg).pixels
        odom = odometry.at(done.entry.t_ns)
        pixels: dict[int, tuple[float, float]] = {}
        map_odom = None
        if isinstance(est, PoseEstimate):
            map_odom = compose((est.x, est.y, est.theta), inverse(odom))
            if est.landmark_ids:
                ids = list(est.landmark_ids)
                p_world = lm.positions[[lm.index_of(i) for i in ids]]
                px, ok = predict_pixels(
                    rec.camera, T_world_body_from_pose(est.x, est.y, est.theta), p_world
                )
                pixels = {
                    i: (float(u), float(v))
                    for i, (u, v), good in zip(ids, px, ok, strict=True)
                    if good
                }
        yield FrameContent(
            t_ns=done.entry.t_ns,
            png_path=None if done.image is None else done.entry.path,
            spots=np.asarray(spots, dtype=np.float64).reshape(-1, 2),
            estimate=est,
            landmark_pixels=pixels,
            odom_pose=odom,
            map_odom=map_odom,
            cpu_s=done.cpu_s,
        )


def covariance6(est: PoseEstimate) -> list[float]:
    """The (x, y, theta) covariance as ROS's 6x6 row-major (x, y, z, rotX, rotY, rotZ); the
    unobserved z, roll and pitch entries are 0, as AMCL publishes them."""
    c = np.asarray(est.covariance, dtype=np.float64)
    out = np.zeros((6, 6))
    idx = [0, 1, 5]
    out[np.ix_(idx, idx)] = c
    return [float(v) for v in out.reshape(-1)]


def quaternion_from_matrix(R: npt.ArrayLike) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix, shape (3, 3)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_quat()
    return float(x), float(y), float(z), float(w)


def quaternion_from_yaw(theta: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation about +z by `theta` radians."""
    return 0.0, 0.0, math.sin(0.5 * theta), math.cos(0.5 * theta)


def body_camera(camera: CameraModel) -> tuple[tuple[float, float, float], tuple[float, ...]]:
    """`base_link -> camera` (translation, quaternion x y z w) from the mounting `T_BS`."""
    T = camera.T_body_camera
    return (float(T[0, 3]), float(T[1, 3]), float(T[2, 3])), quaternion_from_matrix(T[:3, :3])


def lit_at(leds: list[LedsChanged], ids: list[int], t_ns: int) -> frozenset[int]:
    """The lit landmarks at `t_ns` (all when the recording has no LED information)."""
    state = None
    for e in leds:
        if e.t_ns > t_ns:
            break
        state = e
    return frozenset(ids) if state is None else state.lit_among(ids)


__all__ = [
    "ExportContent",
    "FrameContent",
    "Odometry",
    "OdometrySample",
    "TimelineItem",
    "TruthPose",
    "body_camera",
    "compose",
    "covariance6",
    "export_content",
    "integrate_wheel_odometry",
    "inverse",
    "lit_at",
    "quaternion_from_matrix",
    "quaternion_from_yaw",
]
