"""What the part of a drive already solved says of the rest: a Gaussian prior on the first
kept pose, every landmark, the wheels and the camera correction, the older poses
marginalised (`WindowPrior`, `marginalise`). The incremental survey (`survey.incremental`)
solves each new window of the drive with it instead of the whole drive again.

Marginalising keyframes 0 .. j-1 of a window keeps exactly what their residuals (the spots
seen from them, the wheels' intervals between them and on to keyframe j), the priors first
stated in the window and the window's own prior said of the rest: with H and g the
information and gradient of those residuals at the solution, split into the eliminated
poses p and the kept unknowns k,

    Lambda = H_kk - H_kp H_pp^-1 H_pk,    b = g_k - H_kp H_pp^-1 g_p,

and the kept unknowns' prior is (x_k - m)^T Lambda (x_k - m) with m = x_k - Lambda^-1 b
(the Schur complement, as a fixed-lag smoother marginalises; the residuals of keyframes j
and later are not in it: the next window has them again). The linearisation is frozen at
the solution (as every marginalising smoother's): a window starts from the prior's mean.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.linalg import cho_factor, cho_solve

from localizer.types import FloatArray
from survey.estimates import weighted_hessian
from survey.layout import Fit, Layout
from survey.normal_equations import BandedSchur
from survey.sparse_lm import GaussianPrior


@dataclass(frozen=True, eq=False)
class WindowPrior:
    """The solved part of a drive, as a prior on what goes on.

    Attributes:
        t_ns: the time of the kept keyframe (the next window's first frame).
        landmark_ids: the landmarks it holds, in the order of `mean`.
        mean: (pose x, y, theta of the kept keyframe unless not `has_pose`, each landmark's
            x, y, z, the wheels' three scales, the camera correction), (3 + 3 L + 3 + C,).
        information: its information matrix, same order, square.
        lead_t_ns, lead_poses: keyframe times and poses already estimated from t_ns on
            (the next window's starting point over the stretch it shares), (P,), (P, 3).
        pixel_scale, odometry_scale: the spots' and the wheels' noise as their residuals
            showed it, in units of the configured sigmas (the next window's residuals are
            scaled by them, so that the prior and the new data share one metric).
        has_pose: whether it holds the kept keyframe's pose (not after a break: the next
            window's first pose is then free).
    """

    t_ns: int
    landmark_ids: tuple[int, ...]
    mean: FloatArray
    information: FloatArray
    lead_t_ns: npt.NDArray[np.int64]
    lead_poses: FloatArray
    pixel_scale: float = 1.0
    odometry_scale: float = 1.0
    has_pose: bool = True

    @property
    def _o(self) -> int:
        return 3 if self.has_pose else 0

    def landmarks(self) -> dict[int, FloatArray]:
        """Each landmark's mean position."""
        o = self._o
        return {
            lid: self.mean[o + 3 * i : o + 3 + 3 * i].copy()
            for i, lid in enumerate(self.landmark_ids)
        }

    def calibration(self) -> FloatArray:
        """The wheels' scales and the camera correction's mean."""
        return self.mean[self._o + 3 * len(self.landmark_ids) :].copy()

    def without_pose(self, t_ns: int) -> WindowPrior:
        """The prior with the kept pose marginalised too (the drive goes on after a break in
        the wheels' record, from the first frame at or after `t_ns`)."""
        if not self.has_pose:
            return self
        info = self.information
        a, b, c = info[3:, 3:], info[3:, :3], info[:3, :3]
        reduced = a - b @ np.linalg.solve(c, b.T)
        return WindowPrior(
            t_ns,
            self.landmark_ids,
            self.mean[3:].copy(),
            0.5 * (reduced + reduced.T),
            np.zeros(0, dtype=np.int64),
            np.zeros((0, 3)),
            self.pixel_scale,
            self.odometry_scale,
            has_pose=False,
        )

    def lead(self, key_t_ns: npt.NDArray[np.int64]) -> FloatArray:
        """Poses for the longest prefix of `key_t_ns` the prior knows (at least the first)."""
        n = min(len(self.lead_t_ns), len(key_t_ns))
        differ = np.flatnonzero(self.lead_t_ns[:n] != key_t_ns[:n])
        n = int(differ[0]) if len(differ) else n
        return self.lead_poses[:n].copy()

    def gaussian(self, lay: Layout) -> GaussianPrior:
        """The prior on a window's unknowns laid out by `lay` (its first pose the kept one;
        every landmark of the prior among `lay.free_ids`)."""
        cols = [0, 1, 2] if self.has_pose else []
        for lid in self.landmark_ids:
            i = lay.free_index[lid]
            cols += [lay.lm0 + 3 * i, lay.lm0 + 3 * i + 1, lay.lm0 + 3 * i + 2]
        cols += list(range(lay.wheel0, lay.n))
        if len(cols) != len(self.mean):
            raise ValueError("survey: the prior and the window estimate different unknowns")
        return GaussianPrior(np.asarray(cols, dtype=np.int64), self.mean, self.information)


def _rows_before(fit: Fit, j: int) -> npt.NDArray[np.bool_]:
    """The residual rows that involve a keyframe before j: its spots, the wheels' intervals
    from it, and every prior stated in the window (they are stated once)."""
    K = fit.lay.n_keys
    M = len(fit.o_key)
    n_rows = len(fit.fun)
    keep = np.zeros(n_rows, dtype=bool)
    obs = np.repeat(fit.o_key < j, 2)
    keep[: 2 * M] = obs
    seg = np.arange(K - 1) < j
    base = 2 * M
    keep[base : base + 2 * (K - 1)] = np.repeat(seg, 2)
    keep[base + 2 * (K - 1) : base + 3 * (K - 1)] = seg
    keep[base + 3 * (K - 1) :] = True
    return keep


def marginalise(fit: Fit, huber_k: float, j: int, previous: WindowPrior | None) -> WindowPrior:
    """The prior that keyframes 0 .. j-1 of `fit` leave on keyframe j and the rest (`j` >= 1).

    The spots and the wheels are weighted by the variance factors their residuals show
    (`survey.estimates.weighted_hessian`), so the prior is the posterior's information,
    not the assumed noise's.
    """
    lay = fit.lay
    if not 1 <= j < lay.n_keys:
        raise ValueError(f"survey: cannot marginalise {j} of {lay.n_keys} keyframes")
    keep = _rows_before(fit, j)
    _, f_pix, f_odo = weighted_hessian(fit, huber_k)
    J = sp.csr_matrix(fit.jac)[keep]
    r = fit.fun[keep]
    M2 = 2 * len(fit.o_key)
    n_odo = 3 * (lay.n_keys - 1)
    group = np.zeros(len(fit.fun))
    group[:M2] = f_pix
    group[M2 : M2 + n_odo] = f_odo
    group[M2 + n_odo :] = 1.0
    a = np.abs(r)
    w = np.where(a <= huber_k, 1.0, huber_k / np.maximum(a, 1e-300)) / group[keep]
    H = (J.T @ sp.diags(w) @ J).tocsc()
    g = J.T @ (w * r)
    if fit.prior is not None:
        H = (H + fit.prior.hessian(lay.n)).tocsc()
        g = g + fit.prior.gradient(fit.x)
    # keep pose j and everything after the poses; the poses after j have no rows here
    cols = np.concatenate([np.arange(3 * (j + 1)), np.arange(lay.lm0, lay.n)])
    sub = H[cols][:, cols]
    d = sub.diagonal()
    sub = sub + sp.diags(1e-12 * np.where(d > 0, d, 1.0))
    schur = BandedSchur(sub, 3 * j)
    info = schur.schur
    gp, gk = g[cols[: 3 * j]], g[cols[3 * j :]]
    b = schur.reduced_rhs(np.concatenate([gp, gk]))
    x_k = fit.x[cols[3 * j :]]
    mean = x_k - cho_solve(cho_factor(info), b)
    mean[2] = x_k[2] + float(np.remainder(mean[2] - x_k[2] + np.pi, 2 * np.pi) - np.pi)
    poses = fit.poses()
    # the noise the first window's residuals showed scales every later window's (each
    # window's own factor still weights its information here, so the prior stays honest)
    scale_pix = float(np.sqrt(f_pix)) if previous is None else previous.pixel_scale
    scale_odo = float(np.sqrt(f_odo)) if previous is None else previous.odometry_scale
    return WindowPrior(
        int(fit.key_t[j]),
        tuple(lay.free_ids),
        mean,
        0.5 * (info + info.T),
        np.asarray(fit.key_t[j:], dtype=np.int64),
        poses[j:].copy(),
        float(np.clip(scale_pix, 0.2, 5.0)),
        float(np.clip(scale_odo, 0.2, 5.0)),
    )
