"""Wheel odometry between keyframes, with the wheels' calibration as unknowns.

The survey's odometry constraint is the motion between two consecutive keyframes as the
wheels measured it (paper eqs. 5-6, summed over the samples in between). The calibration
(left and right wheel scale, wheel base) is estimated with the map, so the motion is
recomputed from the per-wheel distances at every evaluation; everything here is vectorised
over all intervals at once.

Wheel speeds follow the localizer's convention (`localizer.odometry_track`): between two
samples the speed changes linearly (the trapezoid rule), before the first and after the last
sample it stays at that sample's speeds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from localizer.types import FloatArray, IntArray

_NS = 1e-9


@dataclass(frozen=True, eq=False)
class WheelIntervals:
    """Per-wheel distances of the pieces between keyframes.

    Attributes:
        d_left, d_right: distance each wheel rolled in each piece, metres, shape (M,).
        segment: the keyframe interval each piece belongs to (k: from keyframe k to k + 1),
            non-decreasing, shape (M,).
        n_segments: number of keyframe intervals (keyframes - 1).
        starts: index of each segment's first piece, shape (n_segments,) (pieces of an empty
            segment: none; its motion is zero).
    """

    d_left: FloatArray
    d_right: FloatArray
    segment: IntArray
    n_segments: int
    starts: IntArray


def wheel_intervals(odom_t_ns: IntArray, odom_v: FloatArray, key_t_ns: IntArray) -> WheelIntervals:
    """Cut the wheel-speed record at the keyframe times.

    Args:
        odom_t_ns: sample times, ns, increasing, shape (N,), N >= 1.
        odom_v: (v_left, v_right) at those times, m/s, shape (N, 2).
        key_t_ns: keyframe times, ns, increasing, shape (K,), K >= 1.
    """
    t_s = np.asarray(odom_t_ns, dtype=np.int64)
    v = np.asarray(odom_v, dtype=np.float64).reshape(-1, 2)
    keys = np.asarray(key_t_ns, dtype=np.int64)
    if len(t_s) == 0:
        raise ValueError("wheel_intervals: no odometry samples")
    if len(keys) < 1 or np.any(np.diff(keys) <= 0):
        raise ValueError("wheel_intervals: keyframe times must be increasing")
    inner = t_s[(t_s > keys[0]) & (t_s < keys[-1])]
    cuts = np.union1d(keys, inner)
    a, b = cuts[:-1], cuts[1:]
    dt = (b - a) * _NS
    # speeds at the cut times: linear between samples, held before the first / after the last
    t_f = t_s.astype(np.float64)
    va = np.stack([np.interp(a.astype(np.float64), t_f, v[:, i]) for i in range(2)], axis=1)
    vb = np.stack([np.interp(b.astype(np.float64), t_f, v[:, i]) for i in range(2)], axis=1)
    d = 0.5 * (va + vb) * dt[:, None]
    segment = np.searchsorted(keys, a, side="right") - 1
    n_seg = len(keys) - 1
    starts = np.searchsorted(segment, np.arange(n_seg), side="left").astype(np.int64)
    return WheelIntervals(d[:, 0].copy(), d[:, 1].copy(), segment.astype(np.int64), n_seg, starts)


def relative_motions(
    wheels: WheelIntervals,
    wheel_base_m: float,
    scale_left: float = 1.0,
    scale_right: float = 1.0,
    base_scale: float = 1.0,
) -> FloatArray:
    """Motion over each keyframe interval in the frame of its first keyframe.

    Eq. (6) per piece with the calibrated wheels, dT = (s_l d_l + s_r d_r) / 2 and
    dR = (s_r d_r - s_l d_l) / (s_W W); eq. (5) chained inside the interval (each piece along
    its midpoint heading).

    Returns:
        (dx, dy, dtheta) per interval, metres and radians, shape (n_segments, 3).
    """
    out = np.zeros((wheels.n_segments, 3))
    if len(wheels.segment) == 0:
        return out
    dl = scale_left * wheels.d_left
    dr = scale_right * wheels.d_right
    dT = 0.5 * (dl + dr)
    dR = (dr - dl) / (base_scale * wheel_base_m)
    seg = wheels.segment
    cum = np.cumsum(dR)
    first = _segment_firsts(wheels)
    # heading at the start of each piece, relative to its segment's first keyframe
    offset = cum[first[seg]] - dR[first[seg]]
    phi = cum - dR - offset
    mid = phi + 0.5 * dR
    out[:, 0] = np.bincount(seg, dT * np.cos(mid), minlength=wheels.n_segments)
    out[:, 1] = np.bincount(seg, dT * np.sin(mid), minlength=wheels.n_segments)
    out[:, 2] = np.bincount(seg, dR, minlength=wheels.n_segments)
    return out


def segment_lengths(wheels: WheelIntervals) -> tuple[FloatArray, FloatArray]:
    """Distance driven and angle turned (nominal wheels) per interval: (metres, radians)."""
    dT = np.abs(0.5 * (wheels.d_left + wheels.d_right))
    turn = np.abs(wheels.d_right - wheels.d_left)
    n = wheels.n_segments
    dist: FloatArray = np.bincount(wheels.segment, dT, minlength=n).astype(np.float64)
    turned: FloatArray = np.bincount(wheels.segment, turn, minlength=n).astype(np.float64)
    return dist, turned


def _segment_firsts(wheels: WheelIntervals) -> IntArray:
    """Index of the first piece of each segment (clipped for empty trailing segments)."""
    return np.minimum(wheels.starts, len(wheels.segment) - 1)


def compose(pose: FloatArray, delta: FloatArray) -> FloatArray:
    """Poses (K, 3) moved by deltas (K, 3) given in each pose's own frame."""
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    out = np.empty_like(pose)
    out[:, 0] = pose[:, 0] + c * delta[:, 0] - s * delta[:, 1]
    out[:, 1] = pose[:, 1] + s * delta[:, 0] + c * delta[:, 1]
    out[:, 2] = pose[:, 2] + delta[:, 2]
    return out


def between(a: FloatArray, b: FloatArray) -> FloatArray:
    """Pose b (K, 3) in the frame of pose a (K, 3): (dx, dy, dtheta), dtheta unwrapped."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    out = np.empty_like(a)
    out[:, 0] = c * dx + s * dy
    out[:, 1] = -s * dx + c * dy
    out[:, 2] = b[:, 2] - a[:, 2]
    return out


def dead_reckoning(start: tuple[float, float, float], deltas: FloatArray) -> FloatArray:
    """Keyframe poses (K, 3) from a start pose and K - 1 interval motions (unwrapped)."""
    poses = np.zeros((len(deltas) + 1, 3))
    poses[0] = start
    for k, d in enumerate(deltas):
        poses[k + 1] = compose(poses[k : k + 1], d[None, :])[0]
    return poses
