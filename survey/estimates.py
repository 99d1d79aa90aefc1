"""From a bundle adjustment's solution to the survey's result: each landmark's covariance
(Schur complement of the information matrix, scaled for the residuals and for correlated
views), its residuals and its flags. docs/survey.md."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from survey.layout import Fit, Layout
from survey.problem import BundleConfig, SurveyProblem
from survey.result import LandmarkEstimate, SurveyResult
from survey.sparse_lm import huber_weights

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def marginal_covariances(
    J: sp.csr_matrix, weights: FloatArray, lay: Layout
) -> tuple[FloatArray, FloatArray]:
    """Covariance of the landmarks (3L, 3L) and of the camera correction, with the poses and
    the wheels eliminated (Schur complement of the information matrix J^T W J)."""
    Jw = sp.diags(np.sqrt(weights)) @ J
    H = (Jw.T @ Jw).tocsc()
    interest = np.r_[np.arange(lay.lm0, lay.wheel0), np.arange(lay.cam0, lay.n)]
    nuisance = np.r_[np.arange(0, lay.lm0), np.arange(lay.wheel0, lay.cam0)]
    H_nn = H[nuisance][:, nuisance].tocsc()
    H_ni = H[nuisance][:, interest].toarray()
    H_ii = H[interest][:, interest].toarray()
    lu = splu(H_nn + sp.identity(len(nuisance), format="csc") * 1e-12)
    schur = H_ii - H_ni.T @ lu.solve(H_ni)
    cov = np.linalg.pinv(0.5 * (schur + schur.T))
    k = 3 * len(lay.free_ids)
    return cov[:k, :k], cov[k:, k:]


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
    r = fit.fun
    weights = huber_weights(r, cfg.huber_scale)
    n_obs_rows = 2 * len(fit.o_key)
    dof = max(n_obs_rows - 3 * len(lay.free_ids), 1)
    scale2 = max(float(np.sum(weights[:n_obs_rows] * r[:n_obs_rows] ** 2) / dof), 1.0)
    cov_lm, _ = marginal_covariances(fit.jac, weights, lay)
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
            pos, cov = anchors[lid], np.zeros((3, 3))
        else:
            i = lay.free_index[lid]
            pos = lms[i].copy()
            correlated = max(len(rows) / max(views, 1), 1.0)
            cov = cov_lm[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] * scale2 * correlated
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
        tuple(float(v) for v in c), rms, math.sqrt(scale2),  # type: ignore[arg-type]
        fit.nfev, fit.converged, notes,
    )  # fmt: skip
