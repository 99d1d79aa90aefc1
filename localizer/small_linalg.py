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
