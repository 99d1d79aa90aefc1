"""Landmark tracking (Sec. IV-A.1): search windows and the min-max (bottleneck) assignment.

A tracked landmark is searched for only inside a window around where it is expected. The
window's size follows the paper: the largest image motion between two frames, from the robot's
maximum speed, the frame interval, the image scale (focal length over the ceiling distance)
and the spot's radial distance from the image centre (rotation moves far spots faster), plus
the pose uncertainty propagated to pixels. When windows overlap two landmarks could claim the
same spot (Fig. 8b); the assignment below gives every spot to at most one landmark and
minimises the largest displacement, for any number of landmarks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
from scipy.optimize import linear_sum_assignment

from localizer.types import BoolArray, FloatArray


@dataclass(frozen=True)
class TrackingConfig:
    """Tuning of the search windows.

    Attributes:
        min_half_size_px: smallest window half size, pixels (spot radius plus centroid noise).
        max_half_size_px: beyond this half size the localizer searches the full frame.
        sigma_gate: windows and gates extend this many standard deviations of the predicted
            pixel.
        max_angular_speed_rad_s: fastest turn rate; None derives it from the robot's maximum
            speed and wheel base (2 v_max / W).
        odometry_speed_fraction: when odometry is fresh the unmodelled motion between two
            frames is at most this fraction of the maximum (the rest is predicted).
        speed_change_sigma: standard deviation of a change of each wheel's speed between
            two odometry samples, as a fraction of the maximum speed (a turn in place right
            after driving switches them within one sample): the prediction's second
            hypothesis when the extrapolated one finds no fix.
        slip_sigma: standard deviation of each wheel's slip (its measured travel's error) as
            a fraction of the robot's travel since the last fused fix (a wet patch, a wheel
            spinning): that second hypothesis allows for it too. On an independent
            recording (`bench/foreign` `fast_12hz_slip`, 2 m/s over a patch where the
            wheels spin 12 % and 6 % faster than the floor moves) the odometry turned 1.4 deg
            per frame that the robot did not; well-fitting fixes of 40 landmarks failed the
            innovation gate after four frames, the dead reckoning went 0.6-0.8 m off and the
            robot was lost on every lap (0: off). Wider (0.5, 1.0) is the loose gate: a glint
            taken for a landmark (docs/design/2026-12-02-foreign-recordings.md).
        edge_check_px: a matched spot this close to the image border is checked after the
            fix: its landmark must project inside the image, near it, at the fixed pose.
        border_px: and at least this far inside the image, pixels.
        ambiguity_log_ratio: a landmark's spot is taken only when every other spot that no
            landmark claims within its gate is less likely by this much (natural log of the
            likelihood ratio, the displacement taken as Gaussian with a standard deviation of
            gate / sigma_gate): an unmapped source (a glint, a lamp) beside a landmark leaves
            that landmark out of the fix instead of being taken for it (4.6: 100:1).
    """

    min_half_size_px: float = 6.0
    max_half_size_px: float = 80.0
    sigma_gate: float = 4.0
    max_angular_speed_rad_s: float | None = None
    odometry_speed_fraction: float = 0.25
    speed_change_sigma: float = 0.5
    slip_sigma: float = 0.1
    edge_check_px: float = 40.0
    border_px: float = 3.0
    ambiguity_log_ratio: float = 4.6

    def __post_init__(self) -> None:
        if not 0 < self.min_half_size_px <= self.max_half_size_px:
            raise ValueError("TrackingConfig: need 0 < min_half_size_px <= max_half_size_px")
        if self.sigma_gate <= 0 or not 0 <= self.odometry_speed_fraction <= 1:
            raise ValueError("TrackingConfig: sigma_gate > 0, odometry_speed_fraction in [0, 1]")
        if not self.slip_sigma >= 0:
            raise ValueError(f"TrackingConfig.slip_sigma must be >= 0, got {self.slip_sigma}")
        if self.ambiguity_log_ratio < 0:
            raise ValueError(
                f"TrackingConfig.ambiguity_log_ratio must be >= 0, got {self.ambiguity_log_ratio}"
            )


@overload
def motion_bound_px(
    radial_px: float,
    *,
    max_speed_m_s: float,
    max_angular_speed_rad_s: float,
    dt_s: float,
    scale_px_per_m: float,
) -> float: ...
@overload
def motion_bound_px(
    radial_px: FloatArray,
    *,
    max_speed_m_s: float,
    max_angular_speed_rad_s: float,
    dt_s: float,
    scale_px_per_m: float,
) -> FloatArray: ...
def motion_bound_px(
    radial_px: float | FloatArray,
    *,
    max_speed_m_s: float,
    max_angular_speed_rad_s: float,
    dt_s: float,
    scale_px_per_m: float,
) -> float | FloatArray:
    """Largest image displacement of a spot over `dt_s` (the paper's window size).

    A translation by v dt moves every ceiling spot by v dt * scale pixels; a turn by w dt
    moves a spot at radial distance r from the image centre by about w dt r.

    Args:
        radial_px: distance of each spot from the image centre, pixels, shape (M,) (or
            one float).
        max_speed_m_s: the robot's maximum speed.
        max_angular_speed_rad_s: its maximum turn rate.
        dt_s: time since the spot's position was last known, seconds.
        scale_px_per_m: focal length / distance of the ceiling above the camera.

    Returns:
        shape (M,) (a float for a float), pixels.
    """
    shift, turn = motion_bound_terms(max_speed_m_s, max_angular_speed_rad_s, dt_s, scale_px_per_m)
    r = radial_px if isinstance(radial_px, float) else np.asarray(radial_px, dtype=np.float64)
    return shift + turn * r


def motion_bound_terms(
    max_speed_m_s: float, max_angular_speed_rad_s: float, dt_s: float, scale_px_per_m: float
) -> tuple[float, float]:
    """`motion_bound_px` = shift + turn x radial_px in its two terms: (the translation's
    share, pixels; the turn's, pixels per pixel of radius), computed once per frame."""
    dt = max(dt_s, 0.0)
    return max_speed_m_s * dt * scale_px_per_m, max_angular_speed_rad_s * dt


def window_half_sizes(
    radial_px: FloatArray,
    sigma_px: FloatArray,
    *,
    config: TrackingConfig,
    max_speed_m_s: float,
    max_angular_speed_rad_s: float,
    dt_unpredicted_s: float,
    scale_px_per_m: float,
) -> FloatArray:
    """Half sizes of square search windows, shape (M, 2), pixels.

    half = min_half + sigma_gate * sigma_px + motion bound over the unpredicted interval.

    Args:
        radial_px: shape (M,), distance of each predicted spot from the image centre.
        sigma_px: shape (M,), standard deviation of each predicted pixel.
        dt_unpredicted_s: time over which motion was not predicted by odometry.
    """
    motion = motion_bound_px(
        radial_px,
        max_speed_m_s=max_speed_m_s,
        max_angular_speed_rad_s=max_angular_speed_rad_s,
        dt_s=dt_unpredicted_s,
        scale_px_per_m=scale_px_per_m,
    )
    half = config.min_half_size_px + config.sigma_gate * np.asarray(sigma_px) + motion
    return np.repeat(half[:, None], 2, axis=1)


def bottleneck_assignment(
    cost: FloatArray | list[list[float]], gate: FloatArray | list[float] | float
) -> list[tuple[int, int]]:
    """Match rows (landmarks) to columns (spots) one-to-one, minimising the largest cost.

    Among all matchings with the most pairs within their gates, it picks one whose largest
    cost is smallest (binary search over the sorted costs with a maximum-cardinality matching
    check), then, at that bottleneck, the one with the least total cost. No two rows share a
    column (Sec. IV-A.1, Fig. 8b).

    Args:
        cost: displacement of spot j from landmark i's prediction, shape (M, N) (an array
            or nested lists).
        gate: largest allowed cost per row, shape (M,) or a scalar.

    Returns:
        (row, column) pairs, sorted by row.
    """
    rows = cost.tolist() if isinstance(cost, np.ndarray) else cost
    if not rows or not rows[0]:
        return []
    if isinstance(gate, int | float):
        gates = [float(gate)] * len(rows)
    elif isinstance(gate, list):
        gates = gate
    else:
        gates = np.broadcast_to(np.asarray(gate, dtype=np.float64), (len(rows),)).tolist()
    # The usual tracking case, in plain Python: every landmark sees at most one spot within
    # its gate and no spot is wanted by two landmarks.
    within = [[j for j, v in enumerate(row) if v <= g] for row, g in zip(rows, gates, strict=True)]
    if max(map(len, within)) <= 1:
        taken = [w[0] for w in within if w]
        if len(set(taken)) == len(taken):
            return [(i, w[0]) for i, w in enumerate(within) if w]
    c = np.asarray(rows, dtype=np.float64)
    allowed = c <= np.asarray(gates)[:, None]
    best = _matching_size(allowed)
    levels = np.unique(c[allowed])
    lo, hi = 0, len(levels) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if _matching_size(allowed & (c <= levels[mid])) == best:
            hi = mid
        else:
            lo = mid + 1
    ok = allowed & (c <= levels[lo])
    big = 1e9
    rows, cols = linear_sum_assignment(np.where(ok, c, big))
    return sorted((int(r), int(k)) for r, k in zip(rows, cols, strict=True) if ok[r, k])


def unambiguous_pairs(
    cost: list[list[float]],
    pairs: list[tuple[int, int]],
    sigma_px: list[float],
    log_ratio: float,
) -> tuple[list[tuple[int, int]], list[int]]:
    """Split an assignment into the pairs whose spot is clearly the landmark's and the rest.

    A pair (k, s) is ambiguous when a spot j that no pair uses lies nearly as close to
    landmark k's prediction: with the displacement Gaussian (standard deviation sigma_k), the
    log likelihood ratio of s over j, (d_kj^2 - d_ks^2) / (2 sigma_k^2), is below `log_ratio`.
    Spots taken by other landmarks are explained and never rivals (a dense grid's neighbours).

    Args:
        cost: displacement of spot j from landmark k's prediction, pixels, K x S.
        pairs: (k, s) of an assignment (`bottleneck_assignment`).
        sigma_px: per landmark, the standard deviation of its displacement, pixels, K.
        log_ratio: the least log likelihood ratio of the taken spot over any rival.

    Returns:
        (the unambiguous pairs, the rows k left out as ambiguous).
    """
    taken = {s for _, s in pairs}
    free = [j for j in range(len(cost[0]) if cost else 0) if j not in taken]
    if not free:  # the usual frame: every spot is a landmark's
        return pairs, []
    keep: list[tuple[int, int]] = []
    left: list[int] = []
    for k, s in pairs:
        row = cost[k]
        bound = row[s] * row[s] + 2.0 * log_ratio * sigma_px[k] * sigma_px[k]
        if any(row[j] * row[j] < bound for j in free):
            left.append(k)
        else:
            keep.append((k, s))
    return keep, left


def _matching_size(allowed: BoolArray) -> int:
    """Size of a maximum matching in a bipartite graph given as a boolean matrix."""
    rows, cols = linear_sum_assignment(~allowed)
    return int(np.count_nonzero(allowed[rows, cols]))


def scale_px_per_m(focal_px: float, ceiling_above_camera_m: float) -> float:
    """Image scale of the ceiling: pixels per metre at `ceiling_above_camera_m` (1 / s, eq. 2)."""
    return focal_px / max(ceiling_above_camera_m, 1e-3)


def default_angular_speed(max_speed_m_s: float, wheel_base_m: float) -> float:
    """Fastest turn of a differential drive: one wheel forward, one back at v_max."""
    return 2.0 * max_speed_m_s / max(wheel_base_m, 1e-3)
