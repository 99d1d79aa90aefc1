"""From a bundle adjustment's solution to the survey's result: each landmark's covariance
(Schur complement of the information matrix, its observations weighted by the noise their
residuals show), its residuals and its flags. docs/survey.md."""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from localizer.types import FloatArray, IntArray
from survey.layout import Fit
from survey.normal_equations import BandedSchur
from survey.problem import BundleConfig, SurveyProblem
from survey.result import LandmarkEstimate, SurveyResult
from survey.tally import Tally, count_views, tallies


def variance_factor(r: FloatArray, huber_k: float, redundancy: int) -> float:
    """A group of residuals' a-posteriori variance of unit weight under the Huber loss:
    sum psi(r)^2 / redundancy over the squared share of residuals inside the threshold
    (Huber 1981, ch. 7: the M-estimator's asymptotic covariance is E[psi^2] / E[psi']^2
    times the least-squares one)."""
    if len(r) == 0:
        return 1.0
    psi = np.clip(r, -huber_k, huber_k)
    inside = float(np.mean(np.abs(r) <= huber_k))
    return float(np.sum(psi**2)) / max(redundancy, 1) / max(inside, 1e-3) ** 2


def weighted_hessian(fit: Fit, huber_k: float) -> tuple[sp.csc_matrix, float, float]:
    """The information matrix J^T W J at the solution (plus the fit's prior), and the
    variance factors of the spots and of the wheels' intervals it was weighted by
    (`variance_factor`)."""
    lay = fit.lay
    r, J = fit.fun, sp.csr_matrix(fit.jac)
    n = J.shape[1]
    n_pix = 2 * len(fit.o_key)
    n_odo = 3 * (lay.n_keys - 1)
    # a spot whose landmark the solution put out of the lens's view is no measurement
    valid = np.repeat(fit.valid, 2)
    f_pix = variance_factor(r[:n_pix][valid], huber_k, int(valid.sum()) - n)
    f_odo = variance_factor(r[n_pix : n_pix + n_odo], huber_k, n_odo)
    a = np.abs(r)
    w = np.where(a <= huber_k, 1.0, huber_k / np.maximum(a, 1e-300))
    w[:n_pix] /= f_pix
    w[n_pix : n_pix + n_odo] /= f_odo
    H = (J.T @ sp.diags(w) @ J).tocsc()
    if fit.prior is not None:
        H = (H + fit.prior.hessian(n)).tocsc()
    return H, f_pix, f_odo


def weighted_information(fit: Fit, huber_k: float) -> tuple[BandedSchur, float]:
    """The information matrix J^T W J at the solution, factored (`BandedSchur`), and the
    spots' a-posteriori standard deviation of unit weight (`marginal_covariances`)."""
    H, f_pix, _ = weighted_hessian(fit, huber_k)
    d = H.diagonal()
    H = H + sp.diags(1e-12 * np.where(d > 0, d, 1.0))
    return BandedSchur(H, fit.lay.lm0), math.sqrt(f_pix)


def marginal_covariances(fit: Fit, huber_k: float) -> tuple[FloatArray, float]:
    """Covariance of every unknown but the poses (the landmarks, anchors included, then the
    wheels and the camera correction, all estimated, none held), and the spots' a-posteriori
    standard deviation of unit weight.

    The covariance is the inverse of the information matrix J^T W J (W: the Huber loss's
    weights at the solution) with the poses eliminated by the Schur complement, each group
    of observations (the spots, the wheels' intervals) weighted by its own variance factor
    estimated from its residuals (`variance_factor`: a variance component estimate, with
    the spots' redundancy taken as their rows minus all unknowns), the priors as stated
    (their sigmas are what staff and the calibration say, not residuals). So no noise level
    is assumed: `pixel_sigma_px` and the wheels' sigmas only shape the loss.
    """
    info, s0 = weighted_information(fit, huber_k)
    return info.reduced_covariance(), s0


def independent_views(positions: FloatArray, spacing_m: float) -> int:
    """Views (robot positions in time order) at least `spacing_m` from the last counted one."""
    return count_views(positions, spacing_m)[0]


def survey_result(
    problem: SurveyProblem,
    cfg: BundleConfig,
    anchors: dict[int, FloatArray],
    fit: Fit,
    labels: IntArray,
    rejected: set[int],
    carried: dict[int, Tally] | None = None,
) -> SurveyResult:
    """The result of `fit`; `carried`: each landmark's evidence from the part of the drive
    solved before it (an incremental survey's marginalised keyframes)."""
    lay = fit.lay
    poses, lms, w, c = lay.split(fit.x)
    cov_all, s0 = marginal_covariances(fit, cfg.huber_scale)
    rough = {int(k): np.asarray(v) for k, v in problem.given.items() if v is not None}
    spacing = cfg.independent_view_m
    here = tallies(problem.observations, fit, labels, rejected, spacing)
    out: dict[int, LandmarkEstimate] = {}
    for lid in sorted(set(lay.free_ids) | set(anchors)):
        t = here.get(lid, Tally())
        if carried is not None and lid in carried:
            t = carried[lid].plus(t, spacing)
        given = anchors.get(lid, rough.get(lid))
        if lid in anchors:
            pos, cov = anchors[lid], np.eye(3) * cfg.anchor_sigma_m**2  # as surveyed
        else:
            i = lay.free_index[lid]
            pos = lms[i].copy()
            cov = cov_all[3 * i : 3 * i + 3, 3 * i : 3 * i + 3]
        flags: list[str] = []
        if t.rms_px > cfg.flag_rms_px:
            flags.append(
                f"residuals {t.rms_px:.1f} px RMS: moved during the drive, or two landmarks "
                "answer to one address"
            )
        if t.set_aside > 0.3 * max(t.sightings, 1):
            flags.append(
                f"{t.set_aside} of its {t.sightings} sightings disagree with the rest: "
                "moved during the drive, or two landmarks answer to one address"
            )
        if given is not None and lid not in anchors:
            moved = float(np.linalg.norm(pos - given))
            if moved > cfg.flag_moved_m:
                flags.append(f"{moved:.2f} m from its given position: moved, or radios swapped?")
        if t.views < cfg.min_views and lid not in anchors:
            continue  # too little to place it: reported as not surveyed (`unseen`)
        if t.conflicts:
            flags.append(f"two spots named {lid} at once in {t.conflicts} frame(s)")
        out[lid] = LandmarkEstimate(
            lid,
            np.asarray(pos, dtype=np.float64),
            cov,
            lid in anchors,
            t.observations,
            t.views,
            t.rms_px,
            t.max_px,
            None if given is None else np.asarray(given),
            tuple(flags),
        )
    unseen = tuple(sorted(set(problem.given) - set(out)))
    ok = fit.valid
    rms = float(math.sqrt(np.mean(fit.err[ok] ** 2))) if np.any(ok) else float("nan")
    notes = (f"{len(rejected)} spot track(s) set aside as not explained by the solution",)
    return SurveyResult(
        out,
        unseen,
        fit.key_t,
        poses,
        (float(w[0]), float(w[1]), float(w[2])),
        tuple(float(v) for v in c),
        rms,
        s0,
        fit.nfev,
        fit.converged,
        notes,
    )
