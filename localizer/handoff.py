"""Hand-off (Sec. IV-A.2, eqs. 3-4): predict landmark pixels from a pose, gate, and check
a re-acquisition against the map's geometry.

Eq. (3) predicts where landmark k appears from the latest pose; here that is the camera's
projection (the 3D generalisation, with the lens model, the mounting and each landmark's own
height). Eq. (4) takes the nearest prediction; we gate it by the pose
uncertainty propagated to pixels, so an unmapped IR source beside a landmark is not taken for
it. After a long dead-reckoning stretch the predictions are poor and nearest-prediction alone
could swap landmarks: `consistent_hypotheses` accepts only assignments whose spots agree with
the map's geometry (their mutual distances on the ceiling).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from localizer.camera import CameraModel, bearings_body_from_pixels
from localizer.geometry import rotation_2d, wrap_angle
from localizer.lens import pixel_from_point
from localizer.types import FloatArray, IntArray

Covariance = FloatArray | Sequence[Sequence[float]]


@dataclass(frozen=True)
class HandoffConfig:
    """Tuning of hand-off and re-acquisition.

    Attributes:
        reacquire_sigma_m: position standard deviation above which a landmark match needs
            the geometric check (the prediction alone is no longer trusted), metres.
        distance_tolerance_m: allowed mismatch between a spot pair's distance on the ceiling
            and the map's, metres (plus `distance_tolerance_frac` of the distance).
        distance_tolerance_frac: relative part of that tolerance.
        max_candidates: with more (landmark, spot) candidates than this (a wide prior over
            many landmarks) the search is not attempted: a partial search could miss the
            right hypothesis and keep a wrong one (the LED identification decides instead).
        prior_gate_chi2: a re-acquired pose must agree with the prior within this
            chi-square value (3 degrees of freedom; 16.3 is 99.9 %).
    """

    reacquire_sigma_m: float = 0.10
    distance_tolerance_m: float = 0.04
    distance_tolerance_frac: float = 0.03
    max_candidates: int = 40
    prior_gate_chi2: float = 16.3


_VECTOR_FILTER_ABOVE = 16  # more candidates than this are pre-filtered by distance with numpy


@dataclass(frozen=True, eq=False)
class Prediction:
    """Landmarks predicted in view, as Python lists (the tracking hot path reads them so);
    `rows`, `pixels` and `sigma_px` give them as arrays.

    Attributes:
        row_list: rows of the landmarks in the map, K.
        pixel_list: predicted pixels (col, row), K.
        sigma_list: standard deviation of each predicted pixel, pixels, K.
    """

    row_list: list[int]
    pixel_list: list[tuple[float, float]]
    sigma_list: list[float]

    def __len__(self) -> int:
        return len(self.row_list)

    @property
    def rows(self) -> IntArray:
        """Map rows, shape (K,)."""
        return np.array(self.row_list, dtype=np.int64)

    @property
    def pixels(self) -> FloatArray:
        """Predicted pixels, shape (K, 2)."""
        return np.array(self.pixel_list, dtype=np.float64).reshape(-1, 2)

    @property
    def sigma_px(self) -> FloatArray:
        """Standard deviation of each predicted pixel, shape (K,)."""
        return np.array(self.sigma_list, dtype=np.float64)


def visible_radius_m(camera: CameraModel, ceiling_above_camera_m: float) -> float:
    """Horizontal distance from the camera beyond which no ceiling landmark can be seen."""
    return ceiling_above_camera_m * math.tan(camera.max_angle_rad) + float(
        np.hypot(*camera.T_body_camera[:2, 3])
    )


def predict_landmarks(
    camera: CameraModel,
    pose: tuple[float, float, float],
    covariance: Covariance,
    positions: FloatArray,
    *,
    candidates: IntArray | None = None,
    scale_px_per_m: float,
    reach_m: float,
) -> Prediction:
    """Eq. (3): predict the pixels of the landmarks in view, and their uncertainty.

    The pixel standard deviation is a first-order bound: a position error of sigma_xy moves
    every spot by about scale * sigma_xy, a heading error of sigma_theta moves a spot at
    radial distance r from the image centre by about r * sigma_theta.

    Args:
        pose: (x, y, theta) of the body.
        covariance: of the pose, 3 x 3 (an array or nested sequences).
        positions: all landmark positions, shape (N, 3).
        candidates: rows to consider (e.g. the lit landmarks); None: all.
        scale_px_per_m: image scale of the ceiling.
        reach_m: skip landmarks horizontally farther than this from the robot (a cheap
            pre-filter before projecting).
    """
    x, y, theta = pose
    if candidates is None and len(positions) <= _VECTOR_FILTER_ABOVE:
        row_list: Sequence[int] = range(len(positions))
        P_list = positions.tolist()
    else:
        rows = np.arange(len(positions)) if candidates is None else np.asarray(candidates)
        if len(rows) > _VECTOR_FILTER_ABOVE:  # a large map: drop the far landmarks at once
            P = positions[rows]
            rows = rows[np.hypot(P[:, 0] - x, P[:, 1] - y) <= reach_m]
        row_list, P_list = rows.tolist(), positions[rows].tolist()
    # Few landmarks: plain floats beat numpy's per-call overhead. Eq. (3) in 3D: a landmark
    # in the camera frame is T_camera_body T_body_world P.
    c, s = math.cos(theta), math.sin(theta)
    (r00, r01, r02, t0), (r10, r11, r12, t1), (r20, r21, r22, t2) = camera.T_camera_body_rows
    sigma_xy = position_sigma_m(covariance)
    sigma_t = math.sqrt(max(float(covariance[2][2]), 0.0))
    (*_, cx), (*_, cy), _ = camera.T_body_camera_rows
    offset_px = scale_px_per_m * math.hypot(cx, cy)
    cu, cv = camera.cu, camera.cv
    kept: list[int] = []
    pixels: list[tuple[float, float]] = []
    sigmas: list[float] = []
    for row, (X, Y, Z) in zip(row_list, P_list, strict=True):
        dx, dy = X - x, Y - y
        if math.hypot(dx, dy) > reach_m:
            continue
        bx, by = c * dx + s * dy, c * dy - s * dx
        px = pixel_from_point(
            camera,
            r00 * bx + r01 * by + r02 * Z + t0,
            r10 * bx + r11 * by + r12 * Z + t1,
            r20 * bx + r21 * by + r22 * Z + t2,
        )
        if px is None:
            continue
        kept.append(row)
        pixels.append(px)
        radial = math.hypot(px[0] - cu, px[1] - cv)
        sigmas.append((radial + offset_px) * sigma_t + scale_px_per_m * sigma_xy)
    return Prediction(kept, pixels, sigmas)


def position_sigma_m(covariance: Covariance) -> float:
    """Standard deviation along the worst direction of the (x, y) block of a covariance:
    the square root of the larger eigenvalue of a 2x2 symmetric matrix (closed form).

    Args:
        covariance: of (x, y, ...), an array or nested sequences, at least 2 x 2.
    """
    a, b, c = float(covariance[0][0]), float(covariance[0][1]), float(covariance[1][1])
    return math.sqrt(max(0.5 * (a + c) + math.hypot(0.5 * (a - c), b), 0.0))


def ceiling_points_body(
    camera: CameraModel, pixels: FloatArray, heights_m: FloatArray
) -> FloatArray:
    """Where each pixel's ray meets the horizontal plane at the given height, body frame.

    Assumes a level body (the check below tolerates the small error of a tilt).

    Args:
        pixels: shape (N, 2); heights_m: landmark heights above the floor, shape (N,).

    Returns:
        (x, y) in the body frame, metres, shape (N, 2).
    """
    b = bearings_body_from_pixels(camera, pixels)
    origin = camera.T_body_camera[:3, 3]
    s = (np.asarray(heights_m, dtype=np.float64) - origin[2]) / np.maximum(b[:, 2], 1e-6)
    out: FloatArray = origin[:2] + b[:, :2] * s[:, None]
    return out


def pose_from_ceiling_points(
    q_body: FloatArray, p_world_xy: FloatArray
) -> tuple[float, float, float]:
    """Planar rigid transform (x, y, theta) with p_world = R(theta) q_body + (x, y).

    Least squares (2D Kabsch); the heading is that of the body. Needs 2+ points.
    """
    qc = q_body.mean(axis=0)
    pc = p_world_xy.mean(axis=0)
    a = q_body - qc
    b = p_world_xy - pc
    theta = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    t = pc - rotation_2d(theta) @ qc
    return float(t[0]), float(t[1]), float(wrap_angle(theta))


def consistent_hypotheses(
    camera: CameraModel,
    prediction: Prediction,
    positions: FloatArray,
    spot_pixels: FloatArray,
    gates_px: FloatArray | list[float],
    config: HandoffConfig,
) -> list[list[tuple[int, int]]]:
    """Assignments of spots to predicted landmarks that agree with the map's geometry.

    Every (landmark, spot) pair within the landmark's gate is a candidate; two candidates are
    compatible when they use different landmarks and spots and the distance between the two
    spots' ceiling points matches the two landmarks' distance in the map. A hypothesis is a
    maximal set of mutually compatible candidates (2 or more) whose ceiling points fit the
    map by a rigid motion (not a mirror image). Symmetric landmark layouts leave several
    hypotheses; the caller decides between them with the prior pose.

    Args:
        prediction: landmarks in view (`predict_landmarks`).
        positions: all landmark positions, shape (N, 3).
        spot_pixels: shape (S, 2).
        gates_px: per predicted landmark, shape (K,).

    Returns:
        Hypotheses as lists of (map row, spot index), the largest first.
    """
    pred_px = prediction.pixels
    k_idx, s_idx = np.nonzero(
        np.hypot(
            pred_px[:, None, 0] - spot_pixels[None, :, 0],
            pred_px[:, None, 1] - spot_pixels[None, :, 1],
        )
        <= np.asarray(gates_px)[:, None]
    )
    if len(k_idx) < 2 or len(k_idx) > config.max_candidates:
        return []  # too few, or too many to search all: no hypothesis is trustworthy
    cand_rows = prediction.rows[k_idx]
    cand_spots = s_idx
    q = ceiling_points_body(camera, spot_pixels[cand_spots], positions[cand_rows, 2])
    P = positions[cand_rows, :2]
    d_seen = np.hypot(q[:, None, 0] - q[None, :, 0], q[:, None, 1] - q[None, :, 1])
    d_map = np.hypot(P[:, None, 0] - P[None, :, 0], P[:, None, 1] - P[None, :, 1])
    tol = config.distance_tolerance_m + config.distance_tolerance_frac * d_map
    compatible = (
        (np.abs(d_seen - d_map) <= tol)
        & (cand_rows[:, None] != cand_rows[None, :])
        & (cand_spots[:, None] != cand_spots[None, :])
    )
    found: set[frozenset[int]] = set()
    n = len(cand_rows)
    for i, j in itertools.combinations(range(n), 2):
        if not compatible[i, j]:
            continue
        members = [i, j]
        for k in range(n):
            if k not in members and all(compatible[k, m] for m in members):
                members.append(k)
        found.add(frozenset(members))
    rigid = []
    for h in found:
        m = sorted(h)
        x, y, th = pose_from_ceiling_points(q[m], P[m])
        fitted = q[m] @ rotation_2d(th).T + (x, y)
        # Mutual distances do not see a mirror image; a rigid fit does.
        if float(np.max(np.hypot(*(fitted - P[m]).T))) <= config.distance_tolerance_m:
            rigid.append(h)
    hyps = sorted(rigid, key=lambda h: (-len(h), sorted(h)))
    return [sorted((int(cand_rows[m]), int(cand_spots[m])) for m in h) for h in hyps]


def hypothesis_pose(
    camera: CameraModel, positions: FloatArray, spot_pixels: FloatArray, hyp: list[tuple[int, int]]
) -> tuple[float, float, float]:
    """Rough pose of a hypothesis from its ceiling points (for the prior check)."""
    rows = np.array([r for r, _ in hyp])
    spots = np.array([s for _, s in hyp])
    q = ceiling_points_body(camera, spot_pixels[spots], positions[rows, 2])
    return pose_from_ceiling_points(q, positions[rows, :2])


def pose_mahalanobis2(
    a: tuple[float, float, float], b: tuple[float, float, float], covariance: FloatArray
) -> float:
    """Squared Mahalanobis distance between two poses (heading difference wrapped)."""
    d = np.array([a[0] - b[0], a[1] - b[1], float(wrap_angle(a[2] - b[2]))])
    try:
        return float(d @ np.linalg.solve(covariance, d))
    except np.linalg.LinAlgError:
        return math.inf
