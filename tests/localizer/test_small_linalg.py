"""The float 3x3 helpers of the hot path against numpy's answers."""

from __future__ import annotations

import numpy as np
import pytest

from localizer.small_linalg import (
    clipped_to_unit_3x3_sym,
    eigenvalues_3x3_sym,
    inverse_3x3_sym,
)


def _six(M: np.ndarray) -> list[float]:
    return [M[0, 0], M[0, 1], M[0, 2], M[1, 1], M[1, 2], M[2, 2]]


def _full(m: list[float]) -> np.ndarray:
    a, b, c, d, e, f = m
    return np.array([[a, b, c], [b, d, e], [c, e, f]])


def _spd(rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(3, 3)) * rng.uniform(0.2, 2.0, size=(3, 1))
    return A @ A.T


def test_eigenvalues_match_numpy_largest_first() -> None:
    rng = np.random.default_rng(0)
    for _ in range(2000):
        M = _spd(rng)
        got = eigenvalues_3x3_sym(_six(M))
        want = np.linalg.eigvalsh(M)[::-1]
        assert np.allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
    assert eigenvalues_3x3_sym([2.0, 0.0, 0.0, 2.0, 0.0, 2.0]) == (2.0, 2.0, 2.0)


@pytest.mark.parametrize("spread", [1.0, 1e-3, 1e-6, 1e-9, 0.0])
def test_the_spectrum_clipped_to_unit_matches_numpy_also_with_eigenvalues_clustered_at_one(
    spread: float,
) -> None:
    """Q diag(clip(lambda, 0, 1)) Q^T, with every count of eigenvalues above 1, and the
    hard case of eigenvalues within `spread` of 1 (the eigenvectors there are ill-defined;
    the answer is not)."""
    rng = np.random.default_rng(1)
    for _ in range(2000):
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        lam = np.abs(1.0 + spread * rng.normal(size=3)) if spread < 1 else _spd(rng).diagonal()
        M = (Q * lam) @ Q.T
        want = (Q * np.clip(lam, 0.0, 1.0)) @ Q.T
        got = _full(clipped_to_unit_3x3_sym(_six(M)))
        assert np.max(np.abs(got - want)) < 1e-6 * max(1.0, float(np.max(lam))), (lam, got, want)
    assert clipped_to_unit_3x3_sym([4.0, 0.0, 0.0, 0.25, 0.0, 9.0]) == pytest.approx(
        [1.0, 0.0, 0.0, 0.25, 0.0, 1.0]
    )


def test_inverse_of_a_singular_matrix_is_none() -> None:
    assert inverse_3x3_sym([1.0, 1.0, 0.0, 1.0, 0.0, 1.0]) is None
    inv = inverse_3x3_sym([2.0, 0.0, 0.0, 4.0, 0.0, 8.0])
    assert inv == pytest.approx([0.5, 0.0, 0.0, 0.25, 0.0, 0.125])
