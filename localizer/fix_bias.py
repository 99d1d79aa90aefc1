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
(`moved_bias`: b_c = T b as the body moves); where the new view's Sigma_b is smaller than
the carried one in some direction, only the part the two share is carried (`carry_bias`:
Cov(b_c, b') = Sigma_b' there), so the joint covariance of state and b stays positive
semi-definite and the difference of two fixes says nothing about the new one's error. A C
left as it was when Sigma_b shrinks claims the new fix's error is the old one whole (the
difference of two fixes reads as white noise alone: fixes of a 30 cm pair sliding along
the image's edge under a poor calibration dragged the pose 35 cm away from every one of
them, `hostile_poor`); scaled down with the covariance (b' = L' L^-1 b_c, fully
correlated) it makes the difference a measurement of the error, and the filter
extrapolates beyond the new fix (`hostile_none`: 3 cm beyond every fix of that pair, and
`disturbed_real` rejected 120 more fixes). When the landmarks change,
the new fix's b is correlated with the old one by the share of landmarks they have in
common (`carried_correlation`, |A n B| / sqrt(|A| |B|): the correlation of two means of
independent per-landmark errors), and C is scaled by it too.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.small_linalg import clipped_to_unit_3x3_sym, inverse_3x3_sym
from localizer.types import FloatArray


def carried_correlation(old: frozenset[int], new: frozenset[int]) -> float:
    """The correlation of the systematic errors of two fixes from the landmark sets `old`
    and `new`: |old n new| / sqrt(|old| |new|) (1 for the same set, 0 for disjoint ones)."""
    if not old or not new:
        return 0.0
    if old == new:  # (the usual case: n / sqrt(n n), exactly)
        return 1.0
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
    (dx, dy) since, the two errors correlated by rho (`carried_correlation`).

    The old error is carried rigidly (`moved_bias`: b_c = T b, covariance R_c = T R_old T^T).
    The new one is b' = rho A b_c + n (n independent of everything before) with A the
    *common part*: in the basis where R_c is the identity and R_bias = diag(lambda)
    (L^-1 R_bias L^-T = Q diag(lambda) Q^T, L the Cholesky factor of R_c),
    A = L Q diag(min(1, lambda)) Q^T L^-1. Where the new view's error is at least as large
    as the old one (lambda >= 1) the old error is carried whole and the new view adds its
    own; where it is smaller (lambda < 1: the pair slid towards the image's centre) only
    the part of the old error the new view shares goes on, Cov(b_c, b') = R_bias there, so
    the difference of the two fixes, b_c - b', says nothing about b' (Cov(b', b_c - b') <= 0).
    Scaling the old error down to the new covariance instead (b' = sqrt(lambda) b_c, fully
    correlated) makes that difference a measurement of the error itself, (1 - sqrt(lambda))
    b_c: the filter then extrapolates beyond the new fix by sqrt(lambda) / (1 - sqrt(lambda))
    times the innovation (a gain above one), and the fixes of a 30 cm pair sliding along the
    image's edge carried the pose 3 cm beyond every one of them (`hostile_none`, 8.5 cm
    against 5.5 with the white filter). So C' = rho C T^T A^T. The joint covariance of
    state and error stays positive semi-definite when it was (C^T P^-1 C <= R_c gives
    C'^T P^-1 C' <= rho^2 A R_c A^T <= R_bias, since min(1, lambda)^2 <= lambda)."""
    rows = [[rho * (c0 - dy_m * c2), rho * (c1 + dx_m * c2), rho * c2] for c0, c1, c2 in C]
    (a, b, c), (_, d, e), (_, _, f) = R_old
    # R_c = T R_old T^T, T = [[1, 0, -dy], [0, 1, dx], [0, 0, 1]]
    r02, r12 = c - dy_m * f, e + dx_m * f
    r00 = a - 2.0 * dy_m * c + dy_m * dy_m * f
    r01 = b + dx_m * c - dy_m * e - dx_m * dy_m * f
    r11 = d + 2.0 * dx_m * e + dx_m * dx_m * f
    (b00, b01, b02), (_, b11, b12), (_, _, b22) = R_bias
    # the sign of R_bias - R_c from its leading minors (on floats: this runs every frame)
    grow = _leading_minors(b00 - r00, b01 - r01, b02 - r02, b11 - r11, b12 - r12, b22 - f)
    if grow == 1:  # every lambda > 1: the old error is carried whole
        return rows
    if grow == -1:
        # every lambda < 1: A = R_bias R_c^-1, so C' = rows R_c^-1 R_bias
        inv = inverse_3x3_sym([r00, r01, r02, r11, r12, f])
        if inv is None:
            return [[0.0, 0.0, 0.0] for _ in C]
        i00, i01, i02, i11, i12, i22 = inv
        shrunk = []
        for x0, x1, x2 in rows:  # (x R_c^-1) R_bias
            u0 = x0 * i00 + x1 * i01 + x2 * i02
            u1 = x0 * i01 + x1 * i11 + x2 * i12
            u2 = x0 * i02 + x1 * i12 + x2 * i22
            shrunk.append(
                [
                    u0 * b00 + u1 * b01 + u2 * b02,
                    u0 * b01 + u1 * b11 + u2 * b12,
                    u0 * b02 + u1 * b12 + u2 * b22,
                ]
            )
        return shrunk
    R_c = [[r00, r01, r02], [r01, r11, r12], [r02, r12, f]]
    L = _cholesky_3x3(R_c)
    if L is None:  # no systematic error left to be correlated with
        return [[0.0, 0.0, 0.0] for _ in C]
    # (on floats: this branch runs on about half the frames of a turning robot)
    (l00, _, _), (l10, l11, _), (l20, l21, l22) = L
    k00, k11, k22 = 1.0 / l00, 1.0 / l11, 1.0 / l22  # K = L^-1, lower triangular
    k10 = -l10 * k00 * k11
    k21 = -l21 * k11 * k22
    k20 = -(l20 * k00 + l21 * k10) * k22
    # M = K R_bias K^T
    kb0 = (k00 * b00, k00 * b01, k00 * b02)
    kb1 = (k10 * b00 + k11 * b01, k10 * b01 + k11 * b11, k10 * b02 + k11 * b12)
    kb2 = (
        k20 * b00 + k21 * b01 + k22 * b02,
        k20 * b01 + k21 * b11 + k22 * b12,
        k20 * b02 + k21 * b12 + k22 * b22,
    )
    n00, n01, n02, n11, n12, n22 = clipped_to_unit_3x3_sym(
        [
            kb0[0] * k00,
            kb0[0] * k10 + kb0[1] * k11,
            kb0[0] * k20 + kb0[1] * k21 + kb0[2] * k22,
            kb1[0] * k10 + kb1[1] * k11,
            kb1[0] * k20 + kb1[1] * k21 + kb1[2] * k22,
            kb2[0] * k20 + kb2[1] * k21 + kb2[2] * k22,
        ]
    )
    # A^T = K^T N L^T, N = Q diag(min(1, lambda)) Q^T; C' = rows A^T
    t0 = (
        k00 * n00 + k10 * n01 + k20 * n02,
        k00 * n01 + k10 * n11 + k20 * n12,
        k00 * n02 + k10 * n12 + k20 * n22,
    )
    t1 = (k11 * n01 + k21 * n02, k11 * n11 + k21 * n12, k11 * n12 + k21 * n22)
    t2 = (k22 * n02, k22 * n12, k22 * n22)
    g = [
        (t[0] * l00, t[0] * l10 + t[1] * l11, t[0] * l20 + t[1] * l21 + t[2] * l22)
        for t in (t0, t1, t2)
    ]
    return [[x0 * g[0][j] + x1 * g[1][j] + x2 * g[2][j] for j in range(3)] for x0, x1, x2 in rows]


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


def _leading_minors(a: float, b: float, c: float, d: float, e: float, f: float) -> int:
    """The definiteness of the symmetric 3 x 3 matrix [[a, b, c], [b, d, e], [c, e, f]]
    from its leading minors, on floats: 1 positive definite (a > 0, ad - b^2 > 0, det > 0),
    -1 negative definite (its negation positive definite: a < 0, ad - b^2 > 0, det < 0),
    0 neither."""
    m2 = a * d - b * b
    if not m2 > 0.0:
        return 0
    det = a * (d * f - e * e) - b * (b * f - c * e) + c * (b * e - c * d)
    if a > 0.0 and det > 0.0:
        return 1
    if a < 0.0 and det < 0.0:
        return -1
    return 0


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
    (p00, p01, p02, *_), (p10, p11, p12, *_), (p20, p21, p22, *_) = P[0], P[1], P[2]
    (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = C[0], C[1], C[2]
    (b00, b01, b02), (b10, b11, b12), (b20, b21, b22) = R_bias
    (w00, w01, w02), (w10, w11, w12), (w20, w21, w22) = R_white
    # S = H P H^T + H C + C^T H^T + Sigma_b + R_w, symmetrised
    a = p00 + c00 + c00 + b00 + w00
    b = 0.5 * ((p01 + c01 + c10 + b01 + w01) + (p10 + c10 + c01 + b10 + w10))
    c = 0.5 * ((p02 + c02 + c20 + b02 + w02) + (p20 + c20 + c02 + b20 + w20))
    d = p11 + c11 + c11 + b11 + w11
    e = 0.5 * ((p12 + c12 + c21 + b12 + w12) + (p21 + c21 + c12 + b21 + w21))
    f = p22 + c22 + c22 + b22 + w22
    if not (a > 0.0 and a * d - b * b > 0.0):  # positive definite: leading minors > 0
        return None
    inv = inverse_3x3_sym([a, b, c, d, e, f])  # (and det > 0)
    if inv is None:
        return None
    i00, i01, i02, i11, i12, i22 = inv
    y0, y1, y2 = y
    # M = H C + Sigma_b
    m00, m01, m02 = c00 + b00, c01 + b01, c02 + b02
    m10, m11, m12 = c10 + b10, c11 + b11, c12 + b12
    m20, m21, m22 = c20 + b20, c21 + b21, c22 + b22
    # row by row: G = P H^T + C, K = G S^-1, dX = K y, C - K M (written out: for 3-vectors
    # a comprehension costs more than its arithmetic)
    G, K, dX, C_new = [], [], [], []
    for Pi, (x0, x1, x2) in zip(P, C, strict=True):
        g0, g1, g2 = Pi[0] + x0, Pi[1] + x1, Pi[2] + x2
        k0 = g0 * i00 + g1 * i01 + g2 * i02
        k1 = g0 * i01 + g1 * i11 + g2 * i12
        k2 = g0 * i02 + g1 * i12 + g2 * i22
        G.append((g0, g1, g2))
        K.append((k0, k1, k2))
        dX.append(k0 * y0 + k1 * y1 + k2 * y2)
        C_new.append(
            [
                x0 - (k0 * m00 + k1 * m10 + k2 * m20),
                x1 - (k0 * m01 + k1 * m11 + k2 * m21),
                x2 - (k0 * m02 + k1 * m12 + k2 * m22),
            ]
        )
    # P - K S K^T = P - G K^T (K S = G; G S^-1 G^T is symmetric: its upper triangle,
    # mirrored: row j gets its entries left of the diagonal from the rows above it)
    n = len(P)
    P_new: Rows = [[] for _ in range(n)]
    for i, (g0, g1, g2) in enumerate(G):
        Pi, Ri = P[i], P_new[i]
        for j in range(i, n):
            k0, k1, k2 = K[j]
            v = Pi[j] - (g0 * k0 + g1 * k1 + g2 * k2)
            Ri.append(v)
            if j > i:
                P_new[j].append(v)
        if Ri[i] <= 0.0:
            return None
    nis = (
        i00 * y0 * y0
        + i11 * y1 * y1
        + i22 * y2 * y2
        + 2.0 * (i01 * y0 * y1 + i02 * y0 * y2 + i12 * y1 * y2)
    )
    return dX, P_new, C_new, nis
