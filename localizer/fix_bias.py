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
the pair moves across the image). It is carried as a rigid error of the set's map
(`moved_bias`: b_c = T b as the body moves) and, where the new view's Sigma_b is smaller
than the carried one in some direction, read through the new view's covariance,
b' = L' L^-1 b_c (L, L' the Cholesky factors of the carried and the new Sigma_b,
`carry_bias`), so C' = C T^T L^-T L'^T, and the joint covariance of state and b stays
positive semi-definite. A C left as it was when Sigma_b shrinks (even where the joint
covariance allows it) claims the new fix's error is the old one whole: the difference of
two fixes reads as white noise alone, and fixes of a 30 cm pair sliding along the image's
edge under a poor calibration dragged the pose 35 cm away from every one of them
(`hostile_poor` of the robustness matrix). When the landmarks change,
the new fix's b is correlated with the old one by the share of landmarks they have in
common (`carried_correlation`, |A n B| / sqrt(|A| |B|): the correlation of two means of
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


Rows = list[list[float]]


def carry_bias(C: Rows, R_old: Rows, R_bias: Rows, rho: float, dx_m: float, dy_m: float) -> Rows:
    """The cross-covariance (n x 3) with the new fix's systematic error, of covariance
    R_bias, from C, the one with the last fix's error (covariance R_old), the body moved by
    (dx, dy) since, the two errors correlated by rho (`carried_correlation`). On Python
    floats (the tracking hot path).

    The old error, carried rigidly (`moved_bias`: b_c = T b, covariance R_c = T R_old T^T),
    gives rho C T^T. Where the new view's error is smaller than that (R_bias - rho^2 R_c
    not positive definite: the pair slid towards the image's centre, a poor calibration's
    share shrank), the error is not the same any more: it is read through the new view's
    covariance, b' = L' L^-1 b_c (L, L' the Cholesky factors of R_c and R_bias), so
    C' = rho C T^T L^-T L'^T. Left as it was, C would claim that the new fix's error is the
    old one, whole: the difference of two fixes then reads as their white part alone, the
    gain exceeds one, and the fixes of a 30 cm pair sliding along the image's edge under a
    poor calibration dragged the pose 35 cm away from every one of them (`hostile_poor`).
    Either way the joint covariance of state and error stays positive semi-definite when
    it was (C^T P^-1 C <= R_c implies the same for the result against R_bias)."""
    rows = [[rho * (c0 - dy_m * c2), rho * (c1 + dx_m * c2), rho * c2] for c0, c1, c2 in C]
    (a, b, c), (_, d, e), (_, _, f) = R_old
    # R_c = T R_old T^T, T = [[1, 0, -dy], [0, 1, dx], [0, 0, 1]]
    r02, r12 = c - dy_m * f, e + dx_m * f
    r00 = a - 2.0 * dy_m * c + dy_m * dy_m * f
    r01 = b + dx_m * c - dy_m * e - dx_m * dy_m * f
    r11 = d + 2.0 * dx_m * e + dx_m * dx_m * f
    R_c = [[r00, r01, r02], [r01, r11, r12], [r02, r12, f]]
    k = rho * rho
    if _positive_definite([[R_bias[i][j] - k * R_c[i][j] for j in range(3)] for i in range(3)]):
        return rows
    L, L_new = _cholesky_3x3(R_c), _cholesky_3x3(R_bias)
    if L is None or L_new is None:  # no systematic error left to be correlated with
        return [[0.0, 0.0, 0.0] for _ in C]
    (l00, _, _), (l10, l11, _), (l20, l21, l22) = L
    (m00, _, _), (m10, m11, _), (m20, m21, m22) = L_new
    out = []
    for x0, x1, x2 in rows:  # row c -> (L' L^-1 c^T)^T
        u0 = x0 / l00
        u1 = (x1 - l10 * u0) / l11
        u2 = (x2 - l20 * u0 - l21 * u1) / l22
        out.append([m00 * u0, m10 * u0 + m11 * u1, m20 * u0 + m21 * u1 + m22 * u2])
    return out


def _cholesky_3x3(A: Rows) -> Rows | None:
    """The lower Cholesky factor of a symmetric 3 x 3 matrix (its upper triangle read), on
    floats; None when it is not positive definite."""
    (a, b, c), (_, d, e), (_, _, f) = A
    if not a > 0.0:
        return None
    l00 = math.sqrt(a)
    l10, l20 = b / l00, c / l00
    q = d - l10 * l10
    if not q > 0.0:
        return None
    l11 = math.sqrt(q)
    l21 = (e - l20 * l10) / l11
    q = f - l20 * l20 - l21 * l21
    if not q > 0.0:
        return None
    return [[l00, 0.0, 0.0], [l10, l11, 0.0], [l20, l21, math.sqrt(q)]]


def _positive_definite(A: Rows) -> bool:
    """Whether a symmetric 3 x 3 matrix is positive definite (its leading minors), on floats."""
    (a, b, c), (_, d, e), (_, _, f) = A
    if not (a > 0.0 and a * d - b * b > 0.0):
        return False
    return bool(a * (d * f - e * e) - b * (b * f - c * e) + c * (b * e - c * d) > 0.0)


def consider_update(
    P: Rows,
    C: Rows,
    y: list[float],
    R_white: Rows,
    R_bias: Rows,
) -> tuple[list[float], Rows, Rows, float] | None:
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
    # P - K S K^T = P - G K^T (K S = G; G S^-1 G^T is symmetric: its upper triangle)
    P_new = [[0.0] * n for _ in range(n)]
    for i in range(n):
        g0, g1, g2 = G[i]
        Pi, Ri = P[i], P_new[i]
        for j in range(i, n):
            k0, k1, k2 = K[j]
            Ri[j] = P_new[j][i] = Pi[j] - (g0 * k0 + g1 * k1 + g2 * k2)
        if Ri[i] <= 0.0:
            return None
    M = [[C[r][col] + R_bias[r][col] for col in range(3)] for r in range(3)]  # H C + R_bias
    C_new = [[C[i][col] - (K[i][0] * M[0][col] + K[i][1] * M[1][col] + K[i][2] * M[2][col])
              for col in range(3)] for i in range(n)]  # fmt: skip
    nis = (i00 * y0 * y0 + i11 * y1 * y1 + i22 * y2 * y2
           + 2.0 * (i01 * y0 * y1 + i02 * y0 * y2 + i12 * y1 * y2))  # fmt: skip
    return dX, P_new, C_new, nis
