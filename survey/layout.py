"""Where each unknown of the survey's bundle adjustment sits (`Layout`), which residual
depends on which unknown (`sparsity`), and one solution with what it was solved over (`Fit`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from localizer.types import BoolArray, FloatArray, IntArray
from survey.sparse_lm import GaussianPrior

N_CAMERA = 10
"""The camera correction: focal scales - 1 (fu, fv), principal point (du, dv) px, mounting
yaw rad, the change of the first distortion coefficient (k1), mounting roll and pitch rad
(about the body's x and y axes through the camera), the camera's height change m, and the
change of the second distortion coefficient (k2)."""


class Layout:
    """Where each unknown sits in the parameter vector."""

    def __init__(self, n_keys: int, free_ids: list[int], self_calibrate: bool) -> None:
        self.n_keys = n_keys
        self.free_ids = free_ids
        self.free_index = {lid: i for i, lid in enumerate(free_ids)}
        self.pose0 = 0
        self.lm0 = 3 * n_keys
        self.wheel0 = self.lm0 + 3 * len(free_ids)
        self.cam0 = self.wheel0 + 3
        self.n = self.cam0 + (N_CAMERA if self_calibrate else 0)
        self.self_calibrate = self_calibrate

    def groups(self) -> IntArray:
        """Finite-difference groups: unknowns of one group share no residual (a keyframe pose
        touches its spots and its two odometry intervals, so poses three apart can share;
        every landmark touches only its own spots and prior, so all landmarks can)."""
        g = np.empty(self.n, dtype=np.int64)
        k = np.arange(self.n_keys)
        for j in range(3):
            g[3 * k + j] = (k % 3) * 3 + j
            g[self.lm0 + j : self.wheel0 : 3] = 9 + j
            g[self.wheel0 + j] = 12 + j
        g[self.cam0 : self.n] = 15 + np.arange(self.n - self.cam0)
        return g

    def steps(self) -> FloatArray:
        """Finite-difference steps: 1e-6 m and rad, 1e-6 for scales, 1e-4 px."""
        h = np.full(self.n, 1e-6)
        if self.self_calibrate:
            h[self.cam0 + 2 : self.cam0 + 4] = 1e-4
        return h

    def split(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        poses = x[: self.lm0].reshape(-1, 3)
        lms = x[self.lm0 : self.wheel0].reshape(-1, 3)
        wheels = x[self.wheel0 : self.cam0]
        cam = x[self.cam0 : self.n] if self.self_calibrate else np.zeros(N_CAMERA)
        return poses, lms, wheels, cam


@dataclass(eq=False)
class Fit:
    """One bundle adjustment's solution and what it was solved over."""

    lay: Layout
    key_t: IntArray
    x: FloatArray
    o_key: IntArray
    o_id: IntArray
    o_track: IntArray
    o_rows: IntArray  # rows of the observations used, into problem.observations
    err: FloatArray
    valid: BoolArray
    jac: sp.csr_matrix
    fun: FloatArray
    nfev: int
    converged: bool
    prior: GaussianPrior | None = None  # earlier data, marginalised (`survey.marginal`)

    def landmarks(self) -> dict[int, FloatArray]:
        _, lms, _, _ = self.lay.split(self.x)
        return {lid: lms[i].copy() for lid, i in self.lay.free_index.items()}

    def poses(self) -> FloatArray:
        poses, _, _, _ = self.lay.split(self.x)
        return poses


def sparsity(
    lay: Layout, o_key: IntArray, o_free: IntArray, n_rough: int, rough_rows: IntArray
) -> sp.csr_matrix:
    """Which residual depends on which unknown (the Jacobian's sparsity pattern)."""
    rows: list[IntArray] = []
    cols: list[IntArray] = []
    M = len(o_key)
    obs_rows = np.arange(2 * M).reshape(M, 2)
    for a in range(2):
        for j in range(3):
            rows.append(obs_rows[:, a])
            cols.append(3 * o_key + j)
        free = o_free >= 0
        for j in range(3):
            rows.append(obs_rows[free, a])
            cols.append(lay.lm0 + 3 * o_free[free] + j)
        if lay.self_calibrate:
            for j in range(N_CAMERA):
                rows.append(obs_rows[:, a])
                cols.append(np.full(M, lay.cam0 + j))
    n_seg = lay.n_keys - 1
    base = 2 * M
    seg = np.arange(n_seg)
    odo_rows = [base + 2 * seg, base + 2 * seg + 1, base + 2 * n_seg + seg]
    for rr in odo_rows:
        for j in range(3):
            rows += [rr, rr]
            cols += [3 * seg + j, 3 * (seg + 1) + j]
        for j in range(3):
            rows.append(rr)
            cols.append(np.full(n_seg, lay.wheel0 + j))
    r0 = base + 3 * n_seg
    for i, lm in enumerate(rough_rows.tolist()):
        for j in range(3):
            rows.append(np.array([r0 + 3 * i + j]))
            cols.append(np.array([lay.lm0 + 3 * lm + j]))
    r0 += 3 * n_rough
    for j in range(3):
        rows.append(np.array([r0 + j]))
        cols.append(np.array([lay.wheel0 + j]))
    r0 += 3
    if lay.self_calibrate:
        for j in range(N_CAMERA):
            rows.append(np.array([r0 + j]))
            cols.append(np.array([lay.cam0 + j]))
        r0 += N_CAMERA
    R = np.concatenate(rows)
    C = np.concatenate(cols)
    S = sp.coo_matrix((np.ones(len(R)), (R, C)), shape=(r0, lay.n)).tocsr()
    S.data[:] = 1.0
    return S
