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


def weighted_information(fit: Fit, huber_k: float) -> tuple[BandedSchur, float]:
    """The information matrix J^T W J at the solution, factored (`BandedSchur`), and the
    spots' a-posteriori standard deviation of unit weight (`marginal_covariances`)."""
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
    d = H.diagonal()
    H = H + sp.diags(1e-12 * np.where(d > 0, d, 1.0))
    return BandedSchur(H, lay.lm0), math.sqrt(f_pix)


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
    count, last = 0, None
    for p in positions:
        if last is None or float(np.hypot(*(p - last))) >= spacing_m:
            count += 1
            last = p
    return count


def survey_result(
    problem: SurveyProblem,
    cfg: BundleConfig,
    anchors: dict[int, FloatArray],
    fit: Fit,
    labels: IntArray,
    rejected: set[int],
) -> SurveyResult:
    lay = fit.lay
    poses, lms, w, c = lay.split(fit.x)
    cov_all, s0 = marginal_covariances(fit, cfg.huber_scale)
    rough = {int(k): np.asarray(v) for k, v in problem.given.items() if v is not None}
    obs = problem.observations
    out: dict[int, LandmarkEstimate] = {}
    for lid in sorted(set(lay.free_ids) | set(anchors)):
        rows = np.flatnonzero(fit.o_id == lid)
        e = fit.err[rows][fit.valid[rows]]
        views = independent_views(poses[fit.o_key[rows], :2], cfg.independent_view_m)
        rms_px = float(math.sqrt(np.mean(e**2))) if len(e) else float("nan")
        max_px = float(np.max(e)) if len(e) else float("nan")
        given = anchors.get(lid, rough.get(lid))
        if lid in anchors:
            pos, cov = anchors[lid], np.eye(3) * cfg.anchor_sigma_m**2  # as surveyed
        else:
            i = lay.free_index[lid]
            pos = lms[i].copy()
            cov = cov_all[3 * i : 3 * i + 3, 3 * i : 3 * i + 3]
        flags: list[str] = []
        if rms_px > cfg.flag_rms_px:
            flags.append(
                f"residuals {rms_px:.1f} px RMS: moved during the drive, or two landmarks "
                "answer to one address"
            )
        all_rows = (obs.landmark_id == lid) | (labels == lid)
        set_aside = int(
            np.sum(all_rows & np.isin(obs.track, np.fromiter(rejected, dtype=np.int64)))
        )
        if set_aside > 0.3 * max(int(np.sum(all_rows)), 1):
            flags.append(
                f"{set_aside} of its {int(np.sum(all_rows))} sightings disagree with the rest: "
                "moved during the drive, or two landmarks answer to one address"
            )
        if given is not None and lid not in anchors:
            moved = float(np.linalg.norm(pos - given))
            if moved > cfg.flag_moved_m:
                flags.append(f"{moved:.2f} m from its given position: moved, or radios swapped?")
        if views < cfg.min_views and lid not in anchors:
            continue  # too little to place it: reported as not surveyed (`unseen`)
        conflicts = obs.conflicts.get(lid, 0)
        if conflicts:
            flags.append(f"two spots named {lid} at once in {conflicts} frame(s)")
        out[lid] = LandmarkEstimate(
            lid, np.asarray(pos, dtype=np.float64), cov, lid in anchors, len(rows), views,
            rms_px, max_px, None if given is None else np.asarray(given), tuple(flags),
        )  # fmt: skip
    unseen = tuple(sorted(set(problem.given) - set(out)))
    ok = fit.valid
    rms = float(math.sqrt(np.mean(fit.err[ok] ** 2))) if np.any(ok) else float("nan")
    notes = (f"{len(rejected)} spot track(s) set aside as not explained by the solution",)
    return SurveyResult(
        out, unseen, fit.key_t, poses, (float(w[0]), float(w[1]), float(w[2])),
        tuple(float(v) for v in c), rms, s0,
        fit.nfev, fit.converged, notes,
    )  # fmt: skip
