from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from survey.estimates import variance_factor
from survey.normal_equations import BandedSchur


def _arrow(rng: np.random.Generator, n_band: int, n_rest: int) -> sp.csc_matrix:
    """A normal matrix shaped like the survey's: a chain of 3-unknown poses (each meets its
    neighbours only) and a few dense unknowns every pose meets."""
    rows = []
    k = n_band // 3
    for i in range(k - 1):  # relative constraints between neighbouring poses
        a = np.zeros((3, n_band + n_rest))
        a[:, 3 * i : 3 * i + 3] = -np.eye(3)
        a[:, 3 * i + 3 : 3 * i + 6] = np.eye(3)
        a[:, n_band:] = rng.normal(0, 0.1, (3, n_rest))
        rows.append(a)
    for i in range(k):  # observations of each pose with the dense unknowns
        a = np.zeros((4, n_band + n_rest))
        a[:, 3 * i : 3 * i + 3] = rng.normal(0, 1, (4, 3))
        a[:, n_band:] = rng.normal(0, 1, (4, n_rest))
        rows.append(a)
    J = np.vstack(rows)
    return sp.csc_matrix(J.T @ J)


def test_banded_schur_solves_and_inverts_like_a_dense_solver() -> None:
    rng = np.random.default_rng(0)
    H = _arrow(rng, 3 * 40, 7)
    dense = H.toarray()
    b = rng.normal(0, 1, dense.shape[0])
    f = BandedSchur(H, 120)
    np.testing.assert_allclose(f.solve(b), np.linalg.solve(dense, b), rtol=1e-8, atol=1e-10)
    # the Schur complement's inverse is the marginal covariance of the dense unknowns
    np.testing.assert_allclose(
        f.reduced_covariance(), np.linalg.inv(dense)[120:, 120:], rtol=1e-8, atol=1e-12
    )


def test_variance_factor_is_the_noise_the_residuals_show() -> None:
    rng = np.random.default_rng(1)
    r = rng.normal(0, 0.3, 20000)  # residuals in units of an assumed sigma, really 0.3 of it
    assert abs(variance_factor(r, 3.0, len(r) - 100) - 0.09) < 0.005
    # gross outliers count as the threshold, not as themselves (Huber's psi caps them): 40
    # of them at 50 sigma add 40 * 3^2 to the sum, not 40 * 50^2
    r[:40] = 50.0
    assert 0.09 < variance_factor(r, 3.0, len(r) - 100) < 0.09 + 40 * 9 / 19900 + 0.005
