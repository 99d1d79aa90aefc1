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

from localizer.small_linalg import inverse_3x3_sym

FloatArray = npt.NDArray[np.float64]


def carried_correlation(old: frozenset[int], new: frozenset[int]) -> float:
    """The correlation of the systematic errors of two fixes from the landmark sets `old`
    and `new`: |old n new| / sqrt(|old| |new|) (1 for the same set, 0 for disjoint ones)."""
    if not old or not new:
        return 0.0
    return len(old & new) / math.sqrt(len(old) * len(new))


def moved_bias(dx_m: float, dy_m: float) -> FloatArray:
    """T with b' = T b for the same landmarks after the body moved by (dx, dy): their map
    error is a rigid error of the set (a shift and a turn dtheta about its centre), and a
    fix's position is off by the shift plus dtheta times its offset from the centre, so the
    position part changes by dtheta (-dy, dx) while the heading part stays."""
    return np.array([[1.0, 0.0, -dy_m], [0.0, 1.0, dx_m], [0.0, 0.0, 1.0]])


def carry_bias(
    C: FloatArray,
    P: FloatArray,
    R_bias: FloatArray,
    rho: float,
    R_carried: FloatArray | None = None,
) -> FloatArray:
    """The cross-covariance with the new fix's systematic error: rho C, shrunk where the
    new error's covariance R_bias cannot hold that correlation with a state of covariance P
    (the joint covariance would not be positive semi-definite: C^T P^-1 C must stay below
    R_bias; module docstring). P is regularised by 1e-12 of its largest variance (a frozen
    odometry calibration leaves zero rows, where C is zero too).

    R_carried: the covariance of the error C was consistent with, carried to this view
    (T R_old T^T); when R_bias exceeds rho^2 of it the correlation holds and the test is
    skipped (the same answer, cheaply)."""
    C = rho * C
    if not C.any():
        return C
    if R_carried is not None and _positive_definite(R_bias - rho * rho * R_carried):
        return C
    n = len(P)
    jitter = 1e-12 * float(np.max(np.diag(P)))
    M = C.T @ np.linalg.solve(P + jitter * np.eye(n), C)  # C^T P^-1 C
    M = 0.5 * (M + M.T)
    limit = 1.0 - 1e-6
    try:  # the usual case: it holds
        np.linalg.cholesky(limit * R_bias - M)
        return C
    except np.linalg.LinAlgError:
        pass
    try:
        jitter_b = 1e-9 * max(float(np.trace(R_bias)), 1e-30)
        L = np.linalg.cholesky(0.5 * (R_bias + R_bias.T) + jitter_b * np.eye(3))
    except np.linalg.LinAlgError:  # no systematic error left to be correlated with
        return np.zeros_like(C)
    A = np.linalg.solve(L, np.linalg.solve(L, M).T)  # L^-1 M L^-T
    top = float(np.max(np.linalg.eigvalsh(0.5 * (A + A.T))))
    return C if top <= limit else C * math.sqrt(limit / top)


def _positive_definite(A: FloatArray) -> bool:
    """Whether a symmetric 3 x 3 matrix is positive definite (its leading minors), on floats."""
    (a, b, c), (_, d, e), (_, _, f) = A.tolist()
    if not (a > 0.0 and a * d - b * b > 0.0):
        return False
    return bool(a * (d * f - e * e) - b * (b * f - c * e) + c * (b * e - c * d) > 0.0)


def consider_update(
    P: list[list[float]],
    C: list[list[float]],
    y: list[float],
    R_white: list[list[float]],
    R_bias: list[list[float]],
) -> tuple[list[float], list[list[float]], list[list[float]], float] | None:
    """One consider update (module docstring) of a filter over n states whose first three
    are the measured (x, y, theta). On Python floats (nested lists; for 6 states numpy's
    per-call overhead costs more than the arithmetic).

    Args:
        P: state covariance, n x n.
        C: the cross-covariance of the state's error with the fix's systematic error, n x 3.
        y: innovation z - H X, 3.
        R_white: covariance of the fix's white error, 3 x 3.
        R_bias: covariance of its systematic error, 3 x 3.

    Returns:
        (dX n, P n x n, C n x 3, NIS y^T S^-1 y), or None when S or the new P is not
        positive definite (C inconsistent with R_bias: the caller shrinks it).
    """
    S = [[P[r][c] + C[r][c] + C[c][r] + R_bias[r][c] + R_white[r][c] for c in range(3)]
         for r in range(3)]  # fmt: skip
    a, b, c = S[0][0], 0.5 * (S[0][1] + S[1][0]), 0.5 * (S[0][2] + S[2][0])
    d, e, f = S[1][1], 0.5 * (S[1][2] + S[2][1]), S[2][2]
    if not (a > 0.0 and a * d - b * b > 0.0):  # positive definite: leading minors > 0
        return None
    inv = inverse_3x3_sym([a, b, c, d, e, f])  # (and det > 0)
    if inv is None:
        return None
    i00, i01, i02, i11, i12, i22 = inv
    y0, y1, y2 = y
    n = len(P)
    G = [[P[i][0] + C[i][0], P[i][1] + C[i][1], P[i][2] + C[i][2]] for i in range(n)]
    K = [[g0 * i00 + g1 * i01 + g2 * i02, g0 * i01 + g1 * i11 + g2 * i12,
          g0 * i02 + g1 * i12 + g2 * i22] for g0, g1, g2 in G]  # fmt: skip
    dX = [k0 * y0 + k1 * y1 + k2 * y2 for k0, k1, k2 in K]
    # P - K S K^T = P - G K^T (K S = G), symmetrised
    P_new = [[0.0] * n for _ in range(n)]
    for i in range(n):
        Gi, Pi = G[i], P[i]
        for j in range(i, n):
            Kj, Gj, Ki = K[j], G[j], K[i]
            v = Pi[j] - 0.5 * (Gi[0] * Kj[0] + Gi[1] * Kj[1] + Gi[2] * Kj[2]
                               + Gj[0] * Ki[0] + Gj[1] * Ki[1] + Gj[2] * Ki[2])  # fmt: skip
            P_new[i][j] = P_new[j][i] = v
        if P_new[i][i] <= 0.0:
            return None
    M = [[C[r][col] + R_bias[r][col] for col in range(3)] for r in range(3)]  # H C + R_bias
    C_new = [[C[i][col] - (K[i][0] * M[0][col] + K[i][1] * M[1][col] + K[i][2] * M[2][col])
              for col in range(3)] for i in range(n)]  # fmt: skip
    nis = (i00 * y0 * y0 + i11 * y1 * y1 + i22 * y2 * y2
           + 2.0 * (i01 * y0 * y1 + i02 * y0 * y2 + i12 * y1 * y2))  # fmt: skip
    return dX, P_new, C_new, nis
