from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from survey.sparse_lm import grouped_jacobian, huber_cost, huber_weights, levenberg_marquardt


def _problem(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Independent exponentials y = a_i exp(b_i t): unknowns (a_i, b_i), 30 samples each."""
    n = 6
    truth = np.column_stack([rng.uniform(1, 3, n), rng.uniform(-1, 1, n)]).reshape(-1)
    t = np.linspace(0, 1, 30)
    y = np.concatenate([a * np.exp(b * t) for a, b in truth.reshape(-1, 2)])
    return truth, t, y + rng.normal(0, 1e-3, len(y))


def test_grouped_jacobian_equals_the_dense_one() -> None:
    rng = np.random.default_rng(0)
    truth, t, y = _problem(rng)

    def fun(x: np.ndarray) -> np.ndarray:
        return np.concatenate([a * np.exp(b * t) for a, b in x.reshape(-1, 2)]) - y

    n = len(truth) // 2
    S = sp.block_diag([np.ones((30, 2))] * n).tocsc()
    groups = np.tile([0, 1], n)  # every a together, every b together
    x = truth + 0.1
    r = fun(x)
    J = grouped_jacobian(fun, x, r, S, groups, np.full(len(x), 1e-7)).toarray()
    dense = np.column_stack([(fun(x + 1e-7 * e) - r) / 1e-7 for e in np.eye(len(x))])
    np.testing.assert_allclose(J, dense, atol=1e-6)


def test_recovers_the_answer_despite_gross_outliers() -> None:
    rng = np.random.default_rng(1)
    truth, t, y = _problem(rng)
    y = y.copy()
    y[[3, 40, 77, 150]] += 5.0  # four wild samples

    def fun(x: np.ndarray) -> np.ndarray:
        return (np.concatenate([a * np.exp(b * t) for a, b in x.reshape(-1, 2)]) - y) / 1e-3

    n = len(truth) // 2
    S = sp.block_diag([np.ones((30, 2))] * n).tocsc()
    res = levenberg_marquardt(
        fun, np.tile([2.0, 0.0], n), S, np.tile([0, 1], n), np.full(2 * n, 1e-7),
        huber_k=3.0, max_iterations=60,
    )  # fmt: skip
    assert res.converged
    np.testing.assert_allclose(res.x, truth, atol=5e-3)
    # the wild samples end with Huber weights far below one, the good ones at one
    w = huber_weights(res.residuals, 3.0)
    assert w[[3, 40, 77, 150]].max() < 0.01
    assert np.median(w) == 1.0


def test_huber_cost_is_quadratic_inside_and_linear_outside() -> None:
    assert huber_cost(np.array([1.0, -2.0]), 3.0) == 5.0
    assert huber_cost(np.array([5.0]), 3.0) == 2 * 3 * 5 - 9


def test_central_differences_are_exact_on_a_quadratic_where_forward_ones_are_not() -> None:
    """The covariance's Jacobian: central differences carry no O(h) error (on a quadratic
    none at all), the forward ones' O(h) error is information the data do not have."""
    from survey.sparse_lm import GroupedJacobian

    a = np.array([3.0, -2.0, 0.5])

    def fun(x: np.ndarray) -> np.ndarray:
        return a * x**2

    x = np.array([1.0, 2.0, -1.0])
    jac = GroupedJacobian(sp.eye(3, format="csr"), np.zeros(3, dtype=np.int64), np.full(3, 1e-3))
    exact = np.diag(2 * a * x)
    central = jac(fun, x, fun(x), central=True).toarray()
    forward = jac(fun, x, fun(x)).toarray()
    np.testing.assert_allclose(central, exact, atol=1e-9)
    assert np.max(np.abs(forward - exact)) > 1e-4
