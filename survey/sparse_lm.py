"""Levenberg-Marquardt for large sparse robust least squares (the survey's solver).

`scipy.optimize.least_squares` with `jac_sparsity` and LSMR steps crawled on the survey
(hundreds of evaluations from a start off by decimetres), so this module does what bundle
adjusters do: Gauss-Newton steps on the sparse normal equations, solved exactly
(`scipy.sparse.linalg.splu`), with Levenberg-Marquardt damping and iteratively reweighted
Huber weights. The Jacobian comes from forward differences over groups of unknowns that share
no residual (the caller knows the structure: every keyframe pose touches its own spots and
two odometry intervals, every landmark its own spots), so a Jacobian costs one residual
evaluation per group, not per unknown.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from localizer.types import FloatArray, IntArray
from survey.normal_equations import BandedSchur


@dataclass(frozen=True, eq=False)
class LMResult:
    """The solution, its residuals and Jacobian there, and how the solver ended."""

    x: FloatArray
    residuals: FloatArray
    jacobian: sp.csr_matrix
    iterations: int
    evaluations: int
    converged: bool


@dataclass(frozen=True, eq=False)
class GaussianPrior:
    """A quadratic term (x[cols] - mean)^T information (x[cols] - mean) of the cost: what
    data no longer in the problem said of the unknowns `cols`."""

    cols: IntArray
    mean: FloatArray
    information: FloatArray

    def cost(self, x: FloatArray) -> float:
        d = x[self.cols] - self.mean
        return float(d @ self.information @ d)

    def gradient(self, x: FloatArray) -> FloatArray:
        """Half the cost's gradient (the normal equations' right-hand side convention)."""
        g = np.zeros(len(x))
        g[self.cols] = self.information @ (x[self.cols] - self.mean)
        return g

    def hessian(self, n: int) -> sp.csc_matrix:
        """The information placed in an n x n matrix (half the cost's Hessian)."""
        c = np.asarray(self.cols)
        rows = np.repeat(c, len(c))
        cols = np.tile(c, len(c))
        return sp.csc_matrix((self.information.reshape(-1), (rows, cols)), shape=(n, n))


def huber_weights(r: FloatArray, k: float) -> FloatArray:
    """IRLS weights of the Huber loss with threshold k (residuals in sigmas)."""
    a = np.abs(r)
    return np.where(a <= k, 1.0, k / np.maximum(a, 1e-300))


def huber_cost(r: FloatArray, k: float) -> float:
    """Sum of the Huber loss: r^2 within k, 2 k |r| - k^2 beyond."""
    a = np.abs(r)
    return float(np.sum(np.where(a <= k, a * a, 2.0 * k * a - k * k)))


class GroupedJacobian:
    """Forward-difference Jacobians of one sparsity pattern, one residual evaluation per group
    of columns that share no row (the pattern's bookkeeping done once, not per Jacobian)."""

    def __init__(self, sparsity: sp.spmatrix, groups: IntArray, steps: FloatArray) -> None:
        S = sp.csc_matrix(sparsity)
        S.sort_indices()
        self.shape = S.shape
        self.indptr, self.indices = S.indptr, S.indices
        cols = np.repeat(np.arange(S.shape[1]), np.diff(S.indptr))
        self.steps = np.asarray(steps, dtype=np.float64)
        self.inv_step = 1.0 / self.steps[cols]
        g_of = np.asarray(groups)[cols]
        self.groups = [
            (np.flatnonzero(groups == g), np.flatnonzero(g_of == g))
            for g in np.unique(groups).tolist()
        ]

    def __call__(
        self,
        fun: Callable[[FloatArray], FloatArray],
        x: FloatArray,
        r: FloatArray,
        *,
        central: bool = False,
    ) -> sp.csr_matrix:
        """The Jacobian at x (r = fun(x)); `central`: by central differences, twice the
        evaluations, an error of O(h^2) instead of O(h) (for the covariance, where the
        forward differences' error is information the data do not have: along the map's
        gauge, the rotation and scale only the anchors hold, it halved sigmas)."""
        data = np.empty(len(self.indices))
        for cols, nz in self.groups:
            xp = x.copy()
            xp[cols] += self.steps[cols]
            if central:
                xm = x.copy()
                xm[cols] -= self.steps[cols]
                diff = 0.5 * (fun(xp) - fun(xm))
            else:
                diff = fun(xp) - r
            data[nz] = diff[self.indices[nz]] * self.inv_step[nz]
        return sp.csc_matrix((data, self.indices, self.indptr), shape=self.shape).tocsr()


def grouped_jacobian(
    fun: Callable[[FloatArray], FloatArray],
    x: FloatArray,
    r: FloatArray,
    sparsity: sp.spmatrix,
    groups: IntArray,
    steps: FloatArray,
) -> sp.csr_matrix:
    """Forward-difference Jacobian, one evaluation per group of columns that share no row."""
    return GroupedJacobian(sparsity, groups, steps)(fun, x, r)


def levenberg_marquardt(
    fun: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    sparsity: sp.spmatrix,
    groups: IntArray,
    steps: FloatArray,
    *,
    huber_k: float,
    max_iterations: int,
    rtol: float = 1e-7,
    n_banded: int = 0,
    prior: GaussianPrior | None = None,
    central_final: bool = False,
    progress: Callable[[int, float], None] | None = None,
) -> LMResult:
    """Minimise sum rho(fun(x)_i) (Huber, threshold `huber_k`) from x0.

    Args:
        fun: residuals, already divided by their standard deviations, shape (m,).
        sparsity: which residual depends on which unknown, shape (m, n).
        groups: a group number per unknown; unknowns of one group share no residual.
        steps: finite-difference step per unknown.
        max_iterations: Gauss-Newton steps at most.
        rtol: stop when a step lowers the cost by less than this fraction.
        n_banded: the first this many unknowns form a banded block of the normal matrix
            (poses along a trajectory): each step is then solved by its Schur complement
            (`survey.normal_equations.BandedSchur`) instead of a sparse LU of the whole.
        prior: a Gaussian prior on some unknowns (what earlier data said of them, their
            other unknowns marginalised: `survey.marginal`), added to the cost, gradient and
            normal matrix exactly (it is quadratic), not differenced.
        central_final: the returned Jacobian by central differences (for a covariance).
        progress: called with (iteration, cost) after each step.
    """
    jacobian = GroupedJacobian(sparsity, groups, steps)
    x = np.array(x0, dtype=np.float64)
    r = fun(x)
    evaluations = 1

    def total(x: FloatArray, r: FloatArray) -> float:
        return huber_cost(r, huber_k) + (0.0 if prior is None else prior.cost(x))

    cost = total(x, r)
    H_prior = None if prior is None else prior.hessian(len(x))
    lam = 1e-4
    converged = False
    J = jacobian(fun, x, r)
    evaluations += len(jacobian.groups)
    it = 0
    for it in range(1, max_iterations + 1):
        w = huber_weights(r, huber_k)
        Jw = sp.diags(w) @ J
        H = (J.T @ Jw).tocsc()
        g = J.T @ (w * r)
        if prior is not None and H_prior is not None:
            H = (H + H_prior).tocsc()
            g = g + prior.gradient(x)
        d = H.diagonal()
        d = np.where(d > 0, d, 1.0)
        improved = False
        while lam < 1e10:
            A = (H + sp.diags(lam * d)).tocsc()
            try:
                dx = -(BandedSchur(A, n_banded).solve(g) if n_banded else splu(A).solve(g))
            except (RuntimeError, np.linalg.LinAlgError):  # singular: damp more
                lam *= 10.0
                continue
            x_new = x + dx
            r_new = fun(x_new)
            evaluations += 1
            cost_new = total(x_new, r_new)
            if np.isfinite(cost_new) and cost_new < cost:
                improved = True
                rel = (cost - cost_new) / max(cost, 1e-300)
                x, r, cost = x_new, r_new, cost_new
                lam = max(lam / 5.0, 1e-9)
                break
            lam *= 8.0
        if progress is not None:
            progress(it, cost)
        if not improved:
            converged = True  # no descent left at any damping: a minimum
            break
        J = jacobian(fun, x, r)
        evaluations += len(jacobian.groups)
        if rel < rtol:
            converged = True
            break
    if central_final:
        J = jacobian(fun, x, r, central=True)
        evaluations += 2 * len(jacobian.groups)
    return LMResult(x, r, J, it, evaluations, converged)
