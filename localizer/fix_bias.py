"""A fix's systematic error, the same on every frame of the same landmarks: a Schmidt-Kalman
(consider) update of the pose filter.

A landmark fix z = h(X) + b + w carries two kinds of error. w is white: the centroids' own
noise, new on every frame. b is systematic: the survey error of the landmarks in the map and
the calibration's error, the same for every frame that sees the same landmarks. A 30 cm pair
surveyed to 5 mm per axis gives every frame under it the same heading, wrong by up to 1.3 deg;
fused frame after frame as if its error were white, 90 frames claim 0.14 deg, the filter
believes it, drags its odometry calibration along, and carries that heading into the next
dead-reckoning gap (`pairs_patrol_real`, `pairs_turn_real` of the robustness matrix).

b is not estimated (it has no dynamics the fixes could separate from the pose); its
cross-covariance with the filter's error, C = E[e b^T] (6 x 3, e the state error), is carried
along (a consider filter, Schmidt 1966):

    y = z - H X,                    S = H P H^T + H C + C^T H^T + Sigma_b + R_w,
    K = (P H^T + C) S^-1,           X <- X + K y,
    P <- P - K S K^T,               C <- C - K (H C + Sigma_b),

with H = [I 0]. Between frames C is carried by the odometry Jacobian (C <- F C) like the
state's error. Repeated fixes of the same landmarks then measure the motion since the last
one to their white noise, and the pose itself only to their common error: the filter's
heading under a short pair stays as uncertain as that pair's survey makes it, and the
odometry links fixes of different pairs over the whole pass (a baseline of metres) for a
heading that is right.

The systematic error of the same landmarks changes with the view (its covariance does:
the pair moves across the image). It is carried as the same error read through the new
view's covariance, b' = T b with T = L' L^-1 (L, L' the Cholesky factors of the old and the
new Sigma_b, `carry_bias`), so C' = C T^T and the joint covariance of state and b stays
positive definite (a C left as it was when Sigma_b shrinks is not, and the filter's
covariance went indefinite within a second). When the landmarks change, the new fix's b is
correlated with the old one by the share of landmarks they have in common
(`carried_correlation`, |A n B| / sqrt(|A| |B|): the correlation of two means of
independent per-landmark errors), and C is scaled by it too.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def carried_correlation(old: frozenset[int], new: frozenset[int]) -> float:
    """The correlation of the systematic errors of two fixes from the landmark sets `old`
    and `new`: |old n new| / sqrt(|old| |new|) (1 for the same set, 0 for disjoint ones)."""
    if not old or not new:
        return 0.0
    return len(old & new) / math.sqrt(len(old) * len(new))


def bias_factor(R_bias: FloatArray) -> FloatArray:
    """The lower Cholesky factor of a systematic error's covariance (3, 3), regularised
    by 1e-9 of its trace so that a nearly singular one still factors."""
    jitter = 1e-9 * max(float(np.trace(R_bias)), 1e-30)
    L = np.linalg.cholesky(0.5 * (R_bias + R_bias.T) + jitter * np.eye(3))
    return np.asarray(L, dtype=np.float64)


def moved_bias(dx_m: float, dy_m: float) -> FloatArray:
    """T with b' = T b for the same landmarks after the body moved by (dx, dy): their map
    error is a rigid error of the set (a shift and a turn dtheta about its centre), and a
    fix's position is off by the shift plus dtheta times its offset from the centre, so the
    position part changes by dtheta (-dy, dx) while the heading part stays."""
    return np.array([[1.0, 0.0, -dy_m], [0.0, 1.0, dx_m], [0.0, 0.0, 1.0]])


def carry_bias(C: FloatArray, P: FloatArray, L: FloatArray, rho: float) -> FloatArray:
    """The cross-covariance with the new fix's systematic error: rho C, shrunk where the
    new error's covariance (Cholesky factor L) cannot hold that correlation with a state of
    covariance P (the joint covariance would not be positive semi-definite: C^T P^+ C must
    stay below L L^T; module docstring)."""
    C = rho * C
    if not C.any():
        return C
    A = np.linalg.solve(L, C.T)  # L^-1 C^T
    M = A @ np.linalg.pinv(P, hermitian=True) @ A.T
    top = float(np.max(np.linalg.eigvalsh(0.5 * (M + M.T))))
    limit = 1.0 - 1e-6
    return C if top <= limit else C * math.sqrt(limit / top)


def consider_update(
    P: FloatArray,
    C: list[FloatArray],
    y: FloatArray,
    R_white: FloatArray,
    R_bias: list[FloatArray],
) -> tuple[FloatArray, FloatArray, list[FloatArray], float] | None:
    """One consider update (module docstring) of a filter over n states whose first three
    are the measured (x, y, theta), with independent systematic errors b_i.

    Args:
        P: state covariance, (n, n).
        C: for each b_i, the cross-covariance of the state's error with it, (n, 3).
        y: innovation z - H X, (3,).
        R_white: covariance of the fix's white error, (3, 3).
        R_bias: covariance of each b_i, (3, 3).

    Returns:
        (dX (n,), P (n, n), the new C_i (n, 3), NIS y^T S^-1 y), or None when S is not
        positive definite (a C_i inconsistent with its R_bias: the caller shrinks it).
    """
    C_all = sum(C, np.zeros_like(P[:, :3]))
    HC = C_all[:3]
    S = P[:3, :3] + HC + HC.T + sum(R_bias, R_white)
    S = 0.5 * (S + S.T)
    try:
        np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return None
    S_inv = np.linalg.inv(S)
    if not np.all(np.isfinite(S_inv)):
        return None
    K = (P[:, :3] + C_all) @ S_inv
    P_new = P - K @ S @ K.T
    P_new = 0.5 * (P_new + P_new.T)
    if np.any(np.diag(P_new) <= 0.0):
        return None
    C_new = [Ci - K @ (Ci[:3] + Ri) for Ci, Ri in zip(C, R_bias, strict=True)]
    return K @ y, P_new, C_new, float(y @ S_inv @ y)
