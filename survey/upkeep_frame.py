"""What one localized frame says about the landmarks it saw, with its own pose eliminated.

Keeping the map true (`survey.upkeep`, docs/map-upkeep.md) learns landmark positions from the
frames of robots at work. A robot's pose is fixed from the very landmarks being checked, so a
landmark's residual against that pose is biased toward zero (the pose leaned toward it). Here
the pose is an unknown of the frame, as in the survey's bundle adjustment: the frame's spots
are linearized in the pose (3) and in the positions of the K landmarks matched (3K), and the
pose is eliminated (Schur complement). What is left is the frame's information on the
landmark positions (and on the camera's intrinsics, which a robot's frames share: focal
lengths 0.2 % off scale every view like a map 0.2 % too small, and must not be learnt as
one), shape (3K + 4, 3K + 4), with the vector of its residuals, and it is the same
as the leave-one-out residual of each landmark against the pose fixed by the others, jointly
for all of them: the pose's uncertainty and its correlation with every landmark of the fix
are carried, never assumed away. Pure: numpy in, numpy out.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.pose import solve_pose
from localizer.types import FloatArray
from survey.ceiling import ceiling_points_world

_STEP_M = 1e-4
"""Finite-difference step of a landmark position, metres."""
_STEP_POSE = (1e-4, 1e-4, 1e-5)
"""... and of the pose (x, y metres; theta radians)."""
INTRINSICS = 4
"""Camera unknowns after the landmarks': fu and fv relative errors, cu and cv (pixels)."""


@dataclass(frozen=True, eq=False)
class FrameEvidence:
    """One frame's information on the positions of the landmarks it saw, pose eliminated.

    Attributes:
        ids: the K landmarks matched, in the order of the blocks.
        information: shape (3K + 4, 3K + 4), on the landmarks' displacements from the
            positions the frame was linearized at (the map's; 1/m^2), then on the camera's
            intrinsics: the relative errors of fu and fv (scaled by 1 + s) and the principal
            point's error (cu, cv, pixels); rank 2K - 3.
        vector: shape (3K + 4,): information times the displacement the frame alone
            points to (solve with a prior to get it).
        chi2: the frame's squared residuals over their sigmas after the pose fit (2K - 3
            degrees of freedom when the map is right).
    """

    ids: tuple[int, ...]
    information: FloatArray
    vector: FloatArray
    chi2: float


def match_spots(
    camera: CameraModel,
    pose: tuple[float, float, float],
    pixels: npt.ArrayLike,
    positions: npt.ArrayLike,
    *,
    gate_m: float,
    isolation_m: float,
) -> list[tuple[int, int]]:
    """Pair spots with landmarks on the ceiling: (landmark row, spot row) pairs.

    Each spot's ray is placed by `pose` and met with each landmark's own height plane
    (`survey.ceiling`); a pair is kept when they are each other's nearest, within `gate_m`
    of each other, and every other spot and landmark is at least `isolation_m` away from
    both (a glint beside a landmark, or two landmarks close together, are left out).

    Args:
        pixels: shape (N, 2); positions: shape (M, 3), metres.
    """
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    n, m = len(px), len(P)
    if n == 0 or m == 0:
        return []
    rows = np.repeat(np.arange(m), n)
    q, hit = ceiling_points_world(
        camera, np.tile(pose, (m * n, 1)), np.tile(px, (m, 1)), P[rows, 2]
    )
    d = np.where(hit, np.hypot(q[:, 0] - P[rows, 0], q[:, 1] - P[rows, 1]), np.inf).reshape(m, n)
    big = np.full((m + 1, n + 1), np.inf)  # a sentinel row and column: a second-nearest
    big[:m, :n] = d
    by_row = np.sort(big, axis=1)[:, :2]
    by_col = np.sort(big, axis=0)[:2]
    nearest_spot, nearest_lm = np.argmin(d, axis=1), np.argmin(d, axis=0)
    pairs = []
    for j in range(m):
        s = int(nearest_spot[j])
        best = d[j, s]
        if (
            best <= gate_m
            and nearest_lm[s] == j
            and by_row[j, 1] >= isolation_m
            and by_col[1, s] >= isolation_m
        ):
            pairs.append((j, s))
    return pairs


def frame_evidence(
    camera: CameraModel,
    pose: tuple[float, float, float],
    pixels: npt.ArrayLike,
    positions: npt.ArrayLike,
    ids: Sequence[int],
    sigma_px: Callable[[float, float], float],
    *,
    fit_rows: Sequence[int] | None = None,
) -> FrameEvidence | None:
    """The information one frame carries on its landmarks, the pose eliminated.

    Linearizes the pixel of each spot, h(p_k, pose), at the landmarks' map positions and at
    the pose fitted to the spots (`localizer.pose.solve_pose`, from `pose`), then

        Lambda = J_L^T W J_L - J_L^T W J_x (J_x^T W J_x)^-1 J_x^T W J_L
        eta    = J_L^T W r   - J_L^T W J_x (J_x^T W J_x)^-1 J_x^T W r

    with J_L = dh/dp (block diagonal, 2K x 3K) and, as four last columns, the intrinsics'
    (pixels are K times the distorted normalized point: du/ds_u = u - cu, dv/ds_v = v - cv,
    du/dcu = dv/dcv = 1), J_x = dh/dpose
    (2K x 3), W the inverse pixel variances, r the measured minus predicted pixels.

    Args:
        pose: the localizer's estimate (x, y, theta), the fit's start.
        pixels: the spot of each landmark, shape (K, 2), raw pixels; positions: (K, 3).
        ids: the landmarks' IDs (K).
        sigma_px: a spot's standard deviation per axis at pixel (u, v), pixels.
        fit_rows: rows the pose is fitted to (the landmarks the localizer trusted); None:
            all. Only the linearization point depends on it.

    Returns:
        None with fewer than two landmarks, or when the pose cannot be fitted.
    """
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    k = len(px)
    if k < 2 or P.shape != (k, 3) or len(ids) != k:
        return None
    sig = np.array([sigma_px(float(u), float(v)) for u, v in px])
    fit = list(range(k)) if fit_rows is None else list(fit_rows)
    if len(fit) < 2:
        return None
    fix = solve_pose(camera, px[fit], P[fit], initial=pose, pixel_sigma_px=sig[fit].tolist())
    if fix is None:
        return None
    x0 = (fix.x, fix.y, fix.theta)
    T0 = T_world_body_from_pose(*x0)
    # the landmarks and each of them moved along x, y, z, all seen from the fitted pose
    steps = np.repeat(np.eye(3)[None] * _STEP_M, k, axis=0).reshape(3 * k, 3)
    moved = np.repeat(P, 3, axis=0) + steps
    h_all, ok = predict_pixels(camera, T0, np.vstack([P, moved]))
    if not ok[:k].all():
        return None
    h0 = h_all[:k]
    J_L = np.zeros((2 * k, 3 * k + INTRINSICS))
    dh = ((h_all[k:] - np.repeat(h0, 3, axis=0)) / _STEP_M).reshape(k, 3, 2)
    for i in range(k):
        J_L[2 * i : 2 * i + 2, 3 * i : 3 * i + 3] = dh[i].T
    J_L[0::2, 3 * k] = h0[:, 0] - camera.cu
    J_L[1::2, 3 * k + 1] = h0[:, 1] - camera.cv
    J_L[0::2, 3 * k + 2] = 1.0
    J_L[1::2, 3 * k + 3] = 1.0
    J_x = np.zeros((2 * k, 3))
    for a, step in enumerate(_STEP_POSE):
        xa = list(x0)
        xa[a] += step
        ha, _ = predict_pixels(camera, T_world_body_from_pose(*xa), P)
        J_x[:, a] = ((ha - h0) / step).reshape(-1)
    w = np.repeat(1.0 / sig**2, 2)
    r = (px - h0).reshape(-1)
    A_xx = J_x.T @ (w[:, None] * J_x)
    try:
        A_xx_inv = np.linalg.inv(A_xx)
    except np.linalg.LinAlgError:
        return None
    WJ_L = w[:, None] * J_L
    A_lx = WJ_L.T @ J_x
    info = J_L.T @ WJ_L - A_lx @ A_xx_inv @ A_lx.T
    b_x = J_x.T @ (w * r)
    vec = WJ_L.T @ r - A_lx @ (A_xx_inv @ b_x)
    chi2 = float(r @ (w * r) - b_x @ A_xx_inv @ b_x)
    info = 0.5 * (info + info.T)
    return FrameEvidence(tuple(int(i) for i in ids), info, vec, chi2)
