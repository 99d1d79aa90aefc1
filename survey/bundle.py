"""The survey's estimator: a bundle adjustment of the drive and every landmark at once.

Unknowns: the body pose (x, y, theta) at each keyframe, the position (x, y, z) of every
landmark (the anchors too), the wheels' calibration (left and right scale, wheel-base
scale) and, with `self_calibrate`, a correction of the camera (focal scales, principal
point, k1 and k2, the mounting's yaw, roll, pitch and height). Residuals, each divided by
its standard deviation:

- each named spot: predicted minus measured pixel (`predict_pixels`, eq. 3 in 3-D, through the
  lens model), for the keyframe's pose and the landmark's position;
- each keyframe interval: the motion between the two poses minus the motion the wheels
  measured (eqs. 5-6 with the calibrated wheels, `survey.odometry_chain`);
- priors: an anchor's surveyed position (two or more anchors fix the map's frame, to their
  survey's accuracy), a rough position from map.json (tape measure, floor plan), the wheels
  near nominal, the camera correction near zero.

`survey.sparse_lm` minimises the sum with a Huber loss (a spot that is not what its name
says costs linearly, not quadratically): Levenberg-Marquardt on the normal equations, each
step by the Schur complement of the banded poses (`survey.normal_equations`), the Jacobian
by finite differences over groups of unknowns that share no residual. The covariances
(`survey.estimates`) weight the spots and the wheels by the noise their residuals show.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import transform_points
from localizer.types import BoolArray, FloatArray, IntArray
from survey.association import name_by_association, unnamed_reasons
from survey.estimates import survey_result
from survey.initial import initial_guess
from survey.layout import Fit, Layout, sparsity
from survey.marginal import WindowPrior
from survey.naming import name_by_geometry, outlier_tracks
from survey.odometry_chain import between, relative_motions, segment_lengths, wheel_intervals
from survey.problem import BundleConfig, SurveyProblem
from survey.result import SurveyResult
from survey.sparse_lm import levenberg_marquardt

_NS = 1e-9
_OUT_OF_VIEW = 100.0

__all__ = [
    "BundleConfig",
    "FitSolution",
    "SurveyProblem",
    "select_keyframes",
    "solve_fit",
    "solve_survey",
]


def select_keyframes(frame_t_ns: IntArray, frames_seen: IntArray, period_s: float) -> IntArray:
    """Frames (indices) to estimate a pose at: those with observations, one per period."""
    keep: list[int] = []
    last = -math.inf
    for f in np.unique(frames_seen).tolist():
        t = frame_t_ns[f] * _NS
        if t - last >= period_s - 1e-9:
            keep.append(f)
            last = t
    return np.asarray(keep, dtype=np.int64)


def _check(problem: SurveyProblem, continued: bool = False) -> None:
    if len(problem.anchors) < 2:
        raise ValueError(f"survey: needs two or more anchor landmarks, got {len(problem.anchors)}")
    if len(problem.odom_t_ns) == 0:
        raise ValueError("survey: the recording has no odometry (odom0/data.csv is empty)")
    if continued:  # the anchors are held by the prior: they need not be seen again
        return
    seen = problem.observations.seen_ids()
    missing = sorted(set(problem.anchors) - seen)
    if missing:
        raise ValueError(
            f"survey: anchor landmark(s) {', '.join(map(str, missing))} never identified in "
            "the recording; drive under them"
        )


def solve_survey(
    problem: SurveyProblem,
    config: BundleConfig | None = None,
    *,
    ceiling_z_m: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SurveyResult:
    """Estimate every landmark's position (and the drive) from a survey drive.

    The drive is solved in windows from its start that double in length (`window_s`, then
    twice that, ...), each started from the last one's solution and the wheels beyond it,
    then as a whole; after each window the spot tracks
    that its solution cannot explain (`outlier_track_px`: a track named by a blink that was
    in fact another landmark's, or a landmark that moved) are set aside.

    Args:
        problem: the observations, odometry, anchors and rough positions.
        config: tuning.
        ceiling_z_m: where new landmarks start (default: the anchors' mean height).
        progress: called with (windows done, windows) as the solver goes.

    Raises:
        ValueError: fewer than two anchors, an anchor never identified, no odometry, or no
            frame that sees two landmarks with a position.
    """
    cfg = config or BundleConfig()
    sol = solve_fit(problem, cfg, ceiling_z_m=ceiling_z_m, progress=progress)
    result = survey_result(problem, cfg, sol.anchors, sol.fit, sol.labels, sol.rejected)
    why = unnamed_reasons(problem, cfg, sol.fit, sol.labels, set(result.landmarks), sol.doubt)
    return dataclasses.replace(result, unnamed=why)


@dataclass(frozen=True, eq=False)
class FitSolution:
    """A solved drive (or window of one): the adjustment and the names it settled on.

    Attributes:
        fit: the last adjustment. labels: each observation's landmark (-1: unnamed).
        rejected: spot tracks set aside. doubt: landmark -> neighbours it could not be
            told from (`survey.association`). anchors: their surveyed positions.
    """

    fit: Fit
    labels: IntArray
    rejected: set[int]
    doubt: dict[int, set[int]]
    anchors: dict[int, FloatArray]


def solve_fit(
    problem: SurveyProblem,
    cfg: BundleConfig,
    *,
    ceiling_z_m: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    prior: WindowPrior | None = None,
) -> FitSolution:
    """`solve_survey`'s adjustment, names and all, without the result's bookkeeping; with
    `prior`, a window continuing a drive whose earlier part is marginalised into it
    (`survey.incremental`): its first frame is the prior's keyframe."""
    _check(problem, continued=prior is not None)
    # the dense parts are small (a few hundred unknowns): one BLAS thread does them fastest,
    # and OpenBLAS's threads spinning on a busy machine made them fifty times slower
    with threadpool_limits(limits=1, user_api="blas"):
        return _solve(problem, cfg, ceiling_z_m, progress, prior)


def _solve(
    problem: SurveyProblem,
    cfg: BundleConfig,
    ceiling_z_m: float | None,
    progress: Callable[[int, int], None] | None,
    prior: WindowPrior | None,
) -> FitSolution:
    anchors = {int(k): np.asarray(v, dtype=np.float64) for k, v in problem.anchors.items()}
    zc = float(np.mean([p[2] for p in anchors.values()])) if ceiling_z_m is None else ceiling_z_m
    obs = problem.observations
    t_obs = problem.frame_t_ns[obs.frame]
    t0, t1 = int(t_obs.min()), int(t_obs.max())
    ends: list[int] = []
    span = cfg.window_s / _NS
    while t0 + span < t1:  # windows doubling in length: a long drive costs a few solves
        ends.append(int(t0 + span))
        span *= 2.0
    ends.append(t1)
    # names in use: tracks the blinks named clearly; the others wait for geometry to agree
    # (an anchor's every named track at once: the anchors hold the map's frame, and a wrong
    # one is set aside as soon as the solution settles)
    anchor_named = np.isin(obs.landmark_id, list(anchors)) & (obs.name_votes >= 1)
    labels = np.where((obs.name_votes >= cfg.min_votes) | anchor_named, obs.landmark_id, -1)
    rejected: set[int] = set()
    fit: Fit | None = None
    doubt: dict[int, set[int]] = {}
    for i, t_end in enumerate(ends):
        last = i == len(ends) - 1
        budget = cfg.max_iterations if last else cfg.window_iterations
        window = t_obs <= t_end
        for _ in range(max(cfg.naming_rounds if cfg.associate else 3, 1)):
            rows = np.flatnonzero((labels >= 0) & window)
            fit = _adjust(problem, cfg, anchors, rows, labels, zc, fit, budget, window, prior)
            if len(fit.err) and float(np.median(fit.err)) > 2.0 * cfg.pixel_sigma_px:
                break  # not settled yet: judge no track against it
            bad = outlier_tracks(fit, cfg.outlier_track_px) - rejected
            rejected |= bad
            if bad:
                labels[np.isin(obs.track, np.fromiter(bad, dtype=np.int64))] = -1
            named = name_by_geometry(problem, cfg, fit, labels, window, rejected, zc)
            if cfg.associate:
                more, doubt = name_by_association(problem, cfg, fit, labels, window, rejected, zc)
                named += more
            if not bad and not named:
                break
        if progress is not None:
            progress(i + 1, len(ends))
    assert fit is not None
    return FitSolution(fit, labels, rejected, doubt, anchors)


def _adjust(
    problem: SurveyProblem,
    cfg: BundleConfig,
    anchors: dict[int, FloatArray],
    rows: IntArray,
    labels: IntArray,
    zc: float,
    previous: Fit | None,
    budget: int,
    window: BoolArray | None = None,
    prior: WindowPrior | None = None,
) -> Fit:
    """One bundle adjustment over the observations `rows` (and the drive they span).

    Keyframes are taken among the frames of `rows`, and with `window` (a mask over all
    observations) among every frame with a spot in it, named or not: the poses where only
    unnamed spots are seen then follow the wheels, and their covariance gates the naming.
    """
    cam = problem.camera
    obs = problem.observations
    rough = {
        int(k): np.asarray(v, dtype=np.float64) for k, v in problem.given.items() if v is not None
    }
    key_frames = obs.frame[rows] if window is None else obs.frame[window]
    keys = select_keyframes(problem.frame_t_ns, key_frames, cfg.keyframe_period_s)
    if prior is not None:  # the window starts at the prior's keyframe, seen or not
        keys = np.concatenate([np.zeros(1, np.int64), keys[problem.frame_t_ns[keys] > prior.t_ns]])
        if int(problem.frame_t_ns[0]) != prior.t_ns:
            raise ValueError("survey: a window must begin at its prior's keyframe")
    key_of_frame = {int(f): k for k, f in enumerate(keys.tolist())}
    rows = rows[np.array([int(f) in key_of_frame for f in obs.frame[rows].tolist()], dtype=bool)]
    o_key = np.array([key_of_frame[int(f)] for f in obs.frame[rows].tolist()], dtype=np.int64)
    o_id = labels[rows]
    o_px = obs.pixels[rows]
    key_t = problem.frame_t_ns[keys]
    wheels = wheel_intervals(problem.odom_t_ns, problem.odom_v, key_t)
    deltas0 = relative_motions(wheels, problem.wheel_base_m)
    prefix_poses, prefix_lms = None, None
    if prior is not None:
        prefix_poses, prefix_lms = prior.lead(key_t), prior.landmarks()
    if previous is not None:
        n = min(len(previous.key_t), len(key_t))
        same = np.flatnonzero(previous.key_t[:n] != key_t[:n])
        n = int(same[0]) if len(same) else n
        prefix_poses, prefix_lms = previous.poses()[:n], previous.landmarks()
    poses0, est0 = initial_guess(
        cam,
        deltas0,
        o_key,
        o_id,
        o_px,
        anchors,
        rough,
        zc,
        pixel_sigma_px=cfg.pixel_sigma_px,
        prefix_poses=prefix_poses,
        prefix_landmarks=prefix_lms,
    )
    # every landmark is an unknown, the anchors too: held near their surveyed positions by a
    # prior as tight as their survey (`anchor_sigma_m`), so that their error is part of every
    # landmark's covariance instead of being taken as exact
    free_ids = sorted(est0)
    lay = Layout(len(keys), free_ids, cfg.self_calibrate)
    x0 = np.zeros(lay.n)
    x0[: lay.lm0] = poses0.reshape(-1)
    for lid, i in lay.free_index.items():
        x0[lay.lm0 + 3 * i : lay.lm0 + 3 * i + 3] = est0[lid]
    x0[lay.wheel0 : lay.cam0] = 1.0
    if prior is not None:
        x0[lay.wheel0 : lay.n] = prior.calibration()
    if previous is not None:
        x0[lay.wheel0 : lay.n] = previous.x[previous.lay.wheel0 : previous.lay.n]

    o_free = np.array([lay.free_index.get(int(i), -1) for i in o_id.tolist()], dtype=np.int64)
    placed = o_free >= 0  # a landmark whose rays never met the ceiling has no start: left out
    rows, o_key, o_id, o_px, o_free = (
        rows[placed],
        o_key[placed],
        o_id[placed],
        o_px[placed],
        o_free[placed],
    )
    held = {
        **{lid: (p, cfg.rough_sigma_m) for lid, p in rough.items()},
        **{lid: (p, cfg.anchor_sigma_m) for lid, p in anchors.items()},
    }
    # what the prior holds already had its own priors in the window it came from
    carried = set() if prior is None else set(prior.landmark_ids)
    prior_ids = [lid for lid in free_ids if lid in held and lid not in carried]
    calib_prior = 1.0 if prior is None else 0.0
    rough_rows = np.array([lay.free_index[lid] for lid in prior_ids], dtype=np.int64)
    rough_pos = np.array([held[lid][0] for lid in prior_ids]).reshape(-1, 3)
    rough_sig = np.array([held[lid][1] for lid in prior_ids]).reshape(-1, 1)
    dist, turn = segment_lengths(wheels)
    sig_xy = np.sqrt(cfg.odom_sigma_floor_m**2 + cfg.odom_sigma_m_per_sqrt_m**2 * dist)
    sig_th = np.sqrt(
        cfg.odom_heading_floor_rad**2
        + cfg.odom_heading_sigma_rad_per_sqrt_m**2 * dist
        + cfg.odom_heading_sigma_rad_per_sqrt_rad**2 * turn / problem.wheel_base_m
    )
    centre = np.array([cam.cu, cam.cv])
    T_cb = cam.T_camera_body
    t_bc = cam.T_body_camera[:3, 3]
    k1, k2 = float(cam.distortion[0]), float(cam.distortion[1])
    cam_sig = np.array(
        [
            cfg.focal_sigma_rel,
            cfg.focal_sigma_rel,
            cfg.principal_sigma_px,
            cfg.principal_sigma_px,
            cfg.mount_yaw_sigma_rad,
            max(cfg.distortion_sigma_rel * abs(k1), 1e-4),
            cfg.mount_tilt_sigma_rad,
            cfg.mount_tilt_sigma_rad,
            cfg.mount_height_sigma_m,
            max(cfg.distortion_sigma_rel * abs(k2), 1e-4),
        ]
    )
    lens_cache: dict[tuple[float, float], CameraModel] = {(0.0, 0.0): cam}

    def lens(dk1: float, dk2: float) -> CameraModel:
        """The camera with its first two distortion coefficients changed (cached)."""
        key = (dk1, dk2)
        if key not in lens_cache:
            if len(lens_cache) > 8:
                lens_cache.clear()
                lens_cache[(0.0, 0.0)] = cam
            d = np.array(cam.distortion, dtype=np.float64)
            d[0] += dk1
            d[1] += dk2
            lens_cache[key] = dataclasses.replace(cam, distortion=d)
        return lens_cache[key]

    sigma_px = cfg.pixel_sigma_px

    def project(x: FloatArray) -> tuple[FloatArray, BoolArray]:
        poses, lms, _, c = lay.split(x)
        pw = lms[o_free]
        pk = poses[o_key]
        co, si = np.cos(pk[:, 2]), np.sin(pk[:, 2])
        dx, dy = pw[:, 0] - pk[:, 0], pw[:, 1] - pk[:, 1]
        bx, by = co * dx + si * dy, -si * dx + co * dy
        # the camera's mounting corrected: turned by yaw c[4], roll c[6], pitch c[7] about
        # its own centre t and raised by c[8]: p -> Rx^T Ry^T Rz^T (p - t - dz) + t
        ux, uy, uz = bx - t_bc[0], by - t_bc[1], pw[:, 2] - t_bc[2] - c[8]
        cz, sz = math.cos(c[4]), math.sin(c[4])
        ux, uy = cz * ux + sz * uy, -sz * ux + cz * uy
        cy, sy = math.cos(c[7]), math.sin(c[7])
        ux, uz = cy * ux - sy * uz, sy * ux + cy * uz
        cx, sx = math.cos(c[6]), math.sin(c[6])
        uy, uz = cx * uy + sx * uz, -sx * uy + cx * uz
        p_body = np.stack([ux + t_bc[0], uy + t_bc[1], uz + t_bc[2]], axis=1)
        px, valid = pixels_from_points_camera(
            lens(float(c[5]), float(c[9])), transform_points(T_cb, p_body)
        )
        px = centre + (1.0 + c[0:2]) * (px - centre) + c[2:4]
        return px, valid

    def residuals(x: FloatArray) -> FloatArray:
        poses, lms, w, c = lay.split(x)
        px, valid = project(x)
        # a landmark pushed out of the lens's view costs as much as a gross outlier (were it
        # free, the solver would push troublesome landmarks out of view)
        r_obs = np.where(valid[:, None], (px - o_px) / sigma_px, _OUT_OF_VIEW).reshape(-1)
        pred = relative_motions(wheels, problem.wheel_base_m, w[0], w[1], w[2])
        got = between(poses[:-1], poses[1:])
        r_xy = ((got[:, :2] - pred[:, :2]) / sig_xy[:, None]).reshape(-1)
        r_th = np.remainder(got[:, 2] - pred[:, 2] + math.pi, math.tau) - math.pi
        parts = [r_obs, r_xy, r_th / sig_th]
        parts.append(((lms[rough_rows] - rough_pos) / rough_sig).reshape(-1))
        parts.append(calib_prior * (w - 1.0) / cfg.wheel_scale_sigma)
        if lay.self_calibrate:
            parts.append(calib_prior * c / cam_sig)
        return np.concatenate(parts)

    S = sparsity(lay, o_key, o_free, len(rough_rows), rough_rows)
    gauss = None if prior is None else prior.gaussian(lay)
    res = levenberg_marquardt(
        residuals,
        x0,
        S,
        lay.groups(),
        lay.steps(),
        huber_k=cfg.huber_scale,
        max_iterations=budget,
        n_banded=lay.lm0,
        prior=gauss,
        central_final=True,
    )
    px, valid = project(res.x)
    err = np.linalg.norm(px - o_px, axis=1)
    return Fit(
        lay,
        key_t,
        res.x,
        o_key,
        o_id,
        obs.track[rows],
        rows,
        err,
        valid,
        res.jacobian,
        res.residuals,
        res.iterations,
        res.converged,
        gauss,
    )
