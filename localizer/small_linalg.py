"""Small dense linear algebra on Python floats, for hot paths where numpy's per-call overhead
dominates (3x3 systems solved thousands of times a second)."""

from __future__ import annotations

import math


def inverse_3x3_sym(H: list[float]) -> list[float] | None:
    """Inverse of a symmetric positive definite 3x3 matrix given as (h00 h01 h02 h11 h12 h22).

    Returns:
        The inverse in the same order, or None when the matrix is singular or nearly so
        (det below 1e-12 of the product of the diagonal, a scale-free test by Hadamard's
        inequality).
    """
    a, b, c, d, e, f = H
    A00, A01, A02 = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A00 + b * A01 + c * A02
    if not math.isfinite(det) or det <= 1e-12 * abs(a * d * f):
        return None
    A11, A12, A22 = a * f - c * c, b * c - a * e, a * d - b * b
    return [A00 / det, A01 / det, A02 / det, A11 / det, A12 / det, A22 / det]


def eigenvalues_3x3_sym(M: list[float]) -> tuple[float, float, float]:
    """Eigenvalues, largest first, of a symmetric 3x3 matrix given as (m00 m01 m02 m11 m12
    m22): the trigonometric solution of the characteristic cubic (Smith 1961, "Eigenvalues
    of a symmetric 3 x 3 matrix", Comm. ACM 4(4)); exact for a multiple of the identity."""
    a, b, c, d, e, f = M
    off = b * b + c * c + e * e
    q = (a + d + f) / 3.0
    p2 = (a - q) ** 2 + (d - q) ** 2 + (f - q) ** 2 + 2.0 * off
    if not p2 > 0.0:
        return q, q, q
    p = math.sqrt(p2 / 6.0)
    # det((M - q I) / p) / 2, in [-1, 1] but for rounding
    a_, d_, f_ = (a - q) / p, (d - q) / p, (f - q) / p
    b_, c_, e_ = b / p, c / p, e / p
    r = 0.5 * (a_ * (d_ * f_ - e_ * e_) - b_ * (b_ * f_ - c_ * e_) + c_ * (b_ * e_ - c_ * d_))
    phi = math.acos(min(max(r, -1.0), 1.0)) / 3.0
    top = q + 2.0 * p * math.cos(phi)
    low = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    return top, 3.0 * q - top - low, low


def _eigenvector_3x3_sym(M: list[float], lam: float) -> tuple[float, float, float] | None:
    """A unit eigenvector of the symmetric 3x3 `M` (as in `eigenvalues_3x3_sym`) for its
    simple eigenvalue `lam`: the longest cross product of two rows of M - lam I (None when
    every one vanishes: `lam` is not simple)."""
    a, b, c, d, e, f = M
    r0, r1, r2 = (a - lam, b, c), (b, d - lam, e), (c, e, f - lam)
    best, n2 = (0.0, 0.0, 0.0), 0.0
    for u, v in ((r0, r1), (r0, r2), (r1, r2)):
        w = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        m2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
        if m2 > n2:
            best, n2 = w, m2
    scale = a * a + d * d + f * f + 2.0 * (b * b + c * c + e * e) + lam * lam
    if not n2 > 1e-28 * scale * scale:
        return None
    s = 1.0 / math.sqrt(n2)
    return best[0] * s, best[1] * s, best[2] * s


def clipped_to_unit_3x3_sym(M: list[float]) -> list[float]:
    """Q diag(min(1, max(0, lambda))) Q^T of the symmetric 3x3 M = Q diag(lambda) Q^T (both
    in the order of `eigenvalues_3x3_sym`'s argument), on floats.

    The eigenvalues on the side of 1 that holds one of them are moved through that one's
    eigenvector alone (M - (lambda - 1) v v^T, or I - (1 - lambda) v v^T): where that
    eigenvalue is close to another, on the other side of 1, it is close to 1 too, so its
    eigenvector's error (its gap to the other over the rounding) hardly counts. Negative
    eigenvalues (a positive semi-definite M's rounding) are taken as 0 only when lonely
    below 1 among the others above it.
    """
    lams = eigenvalues_3x3_sym(M)
    above = sum(1 for v in lams if v > 1.0)
    if above == 0:
        return list(M)
    if above == 3:
        return [1.0, 0.0, 0.0, 1.0, 0.0, 1.0]
    if above == 1:  # the largest alone above 1: M - (lambda - 1) v v^T
        lam, base, sign = lams[0], list(M), -(lams[0] - 1.0)
    else:  # the smallest alone at or below 1: I - (1 - lambda) v v^T
        lam, base, sign = lams[2], [1.0, 0.0, 0.0, 1.0, 0.0, 1.0], -(1.0 - max(lams[2], 0.0))
    v = _eigenvector_3x3_sym(M, lam)
    if v is None:  # not simple: then it is 1 to rounding, and nothing moves
        return base
    x, y, z = v
    return [
        base[0] + sign * x * x, base[1] + sign * x * y, base[2] + sign * x * z,
        base[3] + sign * y * y, base[4] + sign * y * z, base[5] + sign * z * z,
    ]  # fmt: skip
