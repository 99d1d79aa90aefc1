"""The survey's estimator: a bundle adjustment of the drive and every landmark at once.

Unknowns: the body pose (x, y, theta) at each keyframe, the position (x, y, z) of every
landmark that is not an anchor, the wheels' calibration (left and right scale, wheel-base
scale) and, with `self_calibrate`, a correction of the camera (focal scale, principal point,
mounting yaw). Residuals, each divided by its standard deviation:

- each named spot: predicted minus measured pixel (`predict_pixels`, eq. 3 in 3-D, through the
  lens model), for the keyframe's pose and the landmark's position;
- each keyframe interval: the motion between the two poses minus the motion the wheels
  measured (eqs. 5-6 with the calibrated wheels, `survey.odometry_chain`);
- priors: a rough position from map.json (tape measure, floor plan), the wheels near nominal,
  the camera correction near zero.

The anchors (two or more landmarks held at their surveyed positions) fix the map's frame.
`survey.sparse_lm` minimises the sum with a Huber loss (a spot that is not what its name
says costs linearly, not quadratically): Levenberg-Marquardt on the sparse normal equations,
the Jacobian by finite differences over groups of unknowns that share no residual. Each
landmark's covariance is its block of the inverse information matrix, the poses and wheels
eliminated by a Schur complement, scaled by the
residuals' own variance and by how many of its views were really independent (neighbouring
frames see a landmark through the same calibration error and carry one view's worth of
information, not many).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import transform_points
from survey.ceiling import ceiling_points_world
from survey.initial import initial_guess
from survey.observations import LabelledObservations
from survey.odometry_chain import between, relative_motions, segment_lengths, wheel_intervals
from survey.result import LandmarkEstimate, SurveyResult
from survey.sparse_lm import huber_weights, levenberg_marquardt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
_NS = 1e-9
_OUT_OF_VIEW = 100.0
N_CAMERA = 6
"""The camera correction: focal scales - 1 (fu, fv), principal point (du, dv) px, mounting
yaw rad, and the change of the first distortion coefficient (k1)."""


@dataclass(frozen=True)
class BundleConfig:
    """Tuning of the survey's estimator (SI units).

    Attributes:
        keyframe_period_s: at most one keyframe per this interval (frames in between add
            little but time).
        pixel_sigma_px: standard deviation of a spot centre per axis, pixels.
        huber_scale: residual (in sigmas) beyond which the Huber loss grows linearly.
        odom_sigma_m_per_sqrt_m, odom_sigma_floor_m: translation noise of the wheels over an
            interval: sqrt(floor^2 + a^2 * distance).
        odom_heading_sigma_rad_per_sqrt_m, odom_heading_sigma_rad_per_sqrt_rad,
        odom_heading_floor_rad: heading noise: sqrt(floor^2 + b^2 * distance + c^2 * turned).
        rough_sigma_m: standard deviation of a rough position from map.json, per axis.
        wheel_scale_sigma: prior standard deviation of each wheel calibration factor.
        self_calibrate: estimate the camera correction too.
        focal_sigma_rel, principal_sigma_px, mount_yaw_sigma_rad: its priors;
        distortion_sigma_rel: the first distortion coefficient's, relative to itself.
        max_iterations: Gauss-Newton steps of the final solve, at most.
        window_s: the drive is solved in windows from its start: this long, then twice as
            long, and so on, seconds.
        window_iterations: the same for each window's solve.
        outlier_track_px: a spot track whose median reprojection error exceeds this is set
            aside (misnamed, or its landmark moved), pixels.
        min_votes: blink votes a track's name needs to be used at once; tracks with fewer
            (or none) are named when the solution agrees (`name_radius_m`).
        name_radius_m: a track whose spots meet the ceiling this close to a landmark's
            estimate may take its name.
        name_exclusion_m: ... if no other landmark is this close (unnamed tracks).
        independent_view_m: views of a landmark closer than this (robot travel) count as one
            for its covariance.
        flag_rms_px: a landmark whose residual RMS exceeds this is flagged (moved during the
            drive, or two landmarks answering to one name).
        flag_moved_m: a landmark this far from its given position is flagged (moved, or
            radios swapped).
        min_views: a landmark seen in fewer independent views is not placed (it is reported
            with the unseen ones).
    """

    keyframe_period_s: float = 0.2
    pixel_sigma_px: float = 0.5
    huber_scale: float = 3.0
    odom_sigma_m_per_sqrt_m: float = 0.01
    odom_sigma_floor_m: float = 0.001
    odom_heading_sigma_rad_per_sqrt_m: float = 0.005
    odom_heading_sigma_rad_per_sqrt_rad: float = 0.02
    odom_heading_floor_rad: float = 0.001
    rough_sigma_m: float = 0.3
    wheel_scale_sigma: float = 0.01
    self_calibrate: bool = True
    focal_sigma_rel: float = 0.002
    principal_sigma_px: float = 2.0
    mount_yaw_sigma_rad: float = math.radians(1.0)
    distortion_sigma_rel: float = 0.1
    max_iterations: int = 30
    window_s: float = 30.0
    window_iterations: int = 8
    outlier_track_px: float = 6.0
    min_votes: int = 1
    name_radius_m: float = 0.05
    name_exclusion_m: float = 0.25
    independent_view_m: float = 0.25
    flag_rms_px: float = 2.0
    flag_moved_m: float = 0.5
    min_views: int = 3


@dataclass(frozen=True, eq=False)
class SurveyProblem:
    """Everything the survey estimates from.

    Attributes:
        camera: the surveying camera (as calibrated).
        wheel_base_m: nominal wheel base, metres.
        frame_t_ns: frame times, shape (F,).
        observations: named spots (`survey.observations.label_spot_tracks`).
        odom_t_ns, odom_v: wheel speeds (v_left, v_right) m/s at their times, (N,), (N, 2).
        anchors: landmark id -> surveyed position (3,), metres; two or more.
        given: every other landmark to survey -> its rough position (3,) or None.
    """

    camera: CameraModel
    wheel_base_m: float
    frame_t_ns: IntArray
    observations: LabelledObservations
    odom_t_ns: IntArray
    odom_v: FloatArray
    anchors: dict[int, FloatArray]
    given: dict[int, FloatArray | None] = field(default_factory=dict)


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


def _check(problem: SurveyProblem) -> None:
    if len(problem.anchors) < 2:
        raise ValueError(f"survey: needs two or more anchor landmarks, got {len(problem.anchors)}")
    if len(problem.odom_t_ns) == 0:
        raise ValueError("survey: the recording has no odometry (odom0/data.csv is empty)")
    seen = problem.observations.seen_ids()
    missing = sorted(set(problem.anchors) - seen)
    if missing:
        raise ValueError(
            f"survey: anchor landmark(s) {', '.join(map(str, missing))} never identified in "
            "the recording; drive under them"
        )


class _Layout:
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
class _Fit:
    """One bundle adjustment's solution and what it was solved over."""

    lay: _Layout
    key_t: IntArray
    x: FloatArray
    o_key: IntArray
    o_id: IntArray
    o_track: IntArray
    o_rows: IntArray  # rows of the observations used, into problem.observations
    err: FloatArray
    valid: npt.NDArray[np.bool_]
    jac: sp.csr_matrix
    fun: FloatArray
    nfev: int
    converged: bool

    def landmarks(self) -> dict[int, FloatArray]:
        _, lms, _, _ = self.lay.split(self.x)
        return {lid: lms[i].copy() for lid, i in self.lay.free_index.items()}

    def poses(self) -> FloatArray:
        poses, _, _, _ = self.lay.split(self.x)
        return poses


def solve_survey(
    problem: SurveyProblem,
    config: BundleConfig | None = None,
    *,
    ceiling_z_m: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    debug: Callable[[int, _Fit], None] | None = None,
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
    _check(problem)
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
    fit: _Fit | None = None
    for i, t_end in enumerate(ends):
        last = i == len(ends) - 1
        budget = cfg.max_iterations if last else cfg.window_iterations
        for _ in range(3):
            rows = np.flatnonzero((labels >= 0) & (t_obs <= t_end))
            fit = _adjust(problem, cfg, anchors, rows, labels, zc, fit, budget)
            if debug is not None:
                debug(t_end, fit)
            if float(np.median(fit.err)) > 2.0 * cfg.pixel_sigma_px:
                break  # not settled yet: judge no track against it
            bad = _outlier_tracks(fit, cfg.outlier_track_px) - rejected
            rejected |= bad
            if bad:
                labels[np.isin(obs.track, np.fromiter(bad, dtype=np.int64))] = -1
            named = _name_by_geometry(problem, cfg, fit, labels, t_obs <= t_end, rejected, zc)
            if not bad and not named:
                break
        if progress is not None:
            progress(i + 1, len(ends))
    assert fit is not None
    return _result(problem, cfg, anchors, fit, labels, rejected)


def _name_by_geometry(
    problem: SurveyProblem,
    cfg: BundleConfig,
    fit: _Fit,
    labels: IntArray,
    in_window: npt.NDArray[np.bool_],
    rejected: set[int],
    zc: float,
) -> int:
    """Give names to the tracks not in use yet where the solution agrees (in place).

    Each such track's spots at the keyframes are put on the ceiling from the solved poses.
    A track whose blink named it is taken if its point lies within `name_radius_m` of that
    landmark's estimate (or, for a landmark with no estimate yet, if its other tentative
    tracks agree with it); a track no blink named is given the nearest landmark's name if
    that one is within `name_radius_m` and every other landmark farther than
    `name_exclusion_m`. Returns how many tracks were named.
    """
    obs = problem.observations
    key_index = {int(t): k for k, t in enumerate(fit.key_t.tolist())}
    frame_key = np.array(
        [key_index.get(int(t), -1) for t in problem.frame_t_ns[obs.frame].tolist()]
    )
    todo = np.flatnonzero(
        (labels < 0) & in_window & (frame_key >= 0) & ~np.isin(obs.track, list(rejected))
    )
    if len(todo) == 0:
        return 0
    poses = fit.poses()
    estimates = {**fit.landmarks(), **{int(k): np.asarray(v) for k, v in problem.anchors.items()}}
    ids = np.array(sorted(estimates))
    pos = np.array([estimates[i] for i in ids]).reshape(-1, 3)
    cam = problem.camera
    points: dict[int, FloatArray] = {}
    order = np.argsort(obs.track[todo], kind="stable")
    tracks, starts = np.unique(obs.track[todo][order], return_index=True)
    heights = [
        float(estimates[lid][2]) if lid in estimates else zc
        for lid in obs.landmark_id[todo].tolist()
    ]
    qs, hit = ceiling_points_world(cam, poses[frame_key[todo]], obs.pixels[todo], heights)
    for tr, rows in zip(tracks.tolist(), np.split(order, starts[1:]), strict=True):
        found = qs[rows][hit[rows]]
        if len(found):
            points[int(tr)] = np.median(found, axis=0)
    named = 0
    tentative: dict[int, list[int]] = {}
    for tr, q in points.items():
        rows = np.flatnonzero(obs.track == tr)
        lid = int(obs.landmark_id[rows[0]])
        d = np.hypot(pos[:, 0] - q[0], pos[:, 1] - q[1]) if len(pos) else np.zeros(0)
        if lid >= 0 and lid in estimates:
            if float(np.hypot(*(estimates[lid][:2] - q[:2]))) <= cfg.name_radius_m:
                labels[rows] = lid
                named += 1
        elif lid >= 0:
            tentative.setdefault(lid, []).append(tr)
        elif len(d):
            best = int(np.argmin(d))
            others = np.delete(d, best)
            if d[best] <= cfg.name_radius_m and (
                len(others) == 0 or others.min() > cfg.name_exclusion_m
            ):
                labels[rows] = int(ids[best])
                named += 1
    for lid, trs in tentative.items():
        pts = np.array([points[t] for t in trs])
        centre = np.median(pts, axis=0)
        agree = [
            t
            for t, q in zip(trs, pts, strict=True)
            if np.hypot(*(q[:2] - centre[:2])) <= cfg.name_radius_m
        ]
        if len(agree) > len(trs) / 2:
            labels[np.isin(obs.track, agree)] = lid
            named += len(agree)
    return named


def _outlier_tracks(fit: _Fit, limit_px: float) -> set[int]:
    """Tracks whose median reprojection error exceeds `limit_px` and five times the typical
    track's (a solution that has not settled yet explains nothing well: it rejects nothing).
    """
    err = np.where(fit.valid, fit.err, np.inf)
    order = np.argsort(fit.o_track, kind="stable")
    tracks, starts = np.unique(fit.o_track[order], return_index=True)
    medians = np.array([float(np.median(e)) for e in np.split(err[order], starts[1:])])
    if len(medians) == 0:
        return set()
    bar = max(limit_px, 5.0 * float(np.median(medians)))
    return {int(t) for t, m in zip(tracks.tolist(), medians.tolist(), strict=True) if m > bar}


def _adjust(
    problem: SurveyProblem,
    cfg: BundleConfig,
    anchors: dict[int, FloatArray],
    rows: IntArray,
    labels: IntArray,
    zc: float,
    previous: _Fit | None,
    budget: int,
) -> _Fit:
    """One bundle adjustment over the observations `rows` (and the drive they span)."""
    cam = problem.camera
    obs = problem.observations
    rough = {
        int(k): np.asarray(v, dtype=np.float64) for k, v in problem.given.items() if v is not None
    }
    keys = select_keyframes(problem.frame_t_ns, obs.frame[rows], cfg.keyframe_period_s)
    key_of_frame = {int(f): k for k, f in enumerate(keys.tolist())}
    rows = rows[np.array([int(f) in key_of_frame for f in obs.frame[rows].tolist()], dtype=bool)]
    o_key = np.array([key_of_frame[int(f)] for f in obs.frame[rows].tolist()], dtype=np.int64)
    o_id = labels[rows]
    o_px = obs.pixels[rows]
    key_t = problem.frame_t_ns[keys]
    wheels = wheel_intervals(problem.odom_t_ns, problem.odom_v, key_t)
    deltas0 = relative_motions(wheels, problem.wheel_base_m)
    prefix_poses, prefix_lms = None, None
    if previous is not None:
        n = min(len(previous.key_t), len(key_t))
        same = np.flatnonzero(previous.key_t[:n] != key_t[:n])
        n = int(same[0]) if len(same) else n
        prefix_poses, prefix_lms = previous.poses()[:n], previous.landmarks()
    poses0, est0 = initial_guess(
        cam, deltas0, o_key, o_id, o_px, anchors, rough, zc,
        pixel_sigma_px=cfg.pixel_sigma_px, prefix_poses=prefix_poses,
        prefix_landmarks=prefix_lms,
    )  # fmt: skip
    free_ids = sorted(lid for lid in est0 if lid not in anchors)
    lay = _Layout(len(keys), free_ids, cfg.self_calibrate)
    x0 = np.zeros(lay.n)
    x0[: lay.lm0] = poses0.reshape(-1)
    for lid, i in lay.free_index.items():
        x0[lay.lm0 + 3 * i : lay.lm0 + 3 * i + 3] = est0[lid]
    x0[lay.wheel0 : lay.cam0] = 1.0
    if previous is not None:
        x0[lay.wheel0 : lay.n] = previous.x[previous.lay.wheel0 : previous.lay.n]

    o_free = np.array([lay.free_index.get(int(i), -1) for i in o_id.tolist()], dtype=np.int64)
    o_anchor = np.array([anchors.get(int(i), np.zeros(3)) for i in o_id.tolist()]).reshape(-1, 3)
    is_free = o_free >= 0
    rough_rows = np.array([lay.free_index[lid] for lid in free_ids if lid in rough], dtype=np.int64)
    rough_pos = np.array([rough[lid] for lid in free_ids if lid in rough]).reshape(-1, 3)
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
    k1 = float(cam.distortion[0])
    cam_sig = np.array(
        [
            cfg.focal_sigma_rel, cfg.focal_sigma_rel, cfg.principal_sigma_px,
            cfg.principal_sigma_px,
            cfg.mount_yaw_sigma_rad, max(cfg.distortion_sigma_rel * abs(k1), 1e-4),
        ]
    )  # fmt: skip
    lens_cache: dict[float, CameraModel] = {0.0: cam}

    def lens(dk1: float) -> CameraModel:
        """The camera with its first distortion coefficient changed by dk1 (cached)."""
        if dk1 not in lens_cache:
            if len(lens_cache) > 8:
                lens_cache.clear()
                lens_cache[0.0] = cam
            d = np.array(cam.distortion, dtype=np.float64)
            d[0] += dk1
            lens_cache[dk1] = dataclasses.replace(cam, distortion=d)
        return lens_cache[dk1]

    sigma_px = cfg.pixel_sigma_px

    def project(x: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        poses, lms, _, c = lay.split(x)
        pw = (
            np.where(is_free[:, None], lms[np.maximum(o_free, 0)], o_anchor)
            if len(lms)
            else o_anchor
        )
        pk = poses[o_key]
        co, si = np.cos(pk[:, 2]), np.sin(pk[:, 2])
        dx, dy = pw[:, 0] - pk[:, 0], pw[:, 1] - pk[:, 1]
        bx, by = co * dx + si * dy, -si * dx + co * dy
        # the camera turned by c[4] about its own centre t on the body: p -> Rz(-yaw)(p - t) + t
        c3, s3 = math.cos(c[4]), math.sin(c[4])
        ux, uy = bx - t_bc[0], by - t_bc[1]
        p_body = np.stack(
            [c3 * ux + s3 * uy + t_bc[0], -s3 * ux + c3 * uy + t_bc[1], pw[:, 2]], axis=1
        )
        px, valid = pixels_from_points_camera(lens(float(c[5])), transform_points(T_cb, p_body))
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
        parts.append(((lms[rough_rows] - rough_pos) / cfg.rough_sigma_m).reshape(-1))
        parts.append((w - 1.0) / cfg.wheel_scale_sigma)
        if lay.self_calibrate:
            parts.append(c / cam_sig)
        return np.concatenate(parts)

    S = _sparsity(lay, o_key, o_free, len(rough_rows), rough_rows)
    res = levenberg_marquardt(
        residuals, x0, S, lay.groups(), lay.steps(), huber_k=cfg.huber_scale,
        max_iterations=budget,
    )  # fmt: skip
    px, valid = project(res.x)
    err = np.linalg.norm(px - o_px, axis=1)
    return _Fit(
        lay, key_t, res.x, o_key, o_id, obs.track[rows], rows, err, valid,
        res.jacobian, res.residuals, res.iterations, res.converged,
    )  # fmt: skip


def _sparsity(
    lay: _Layout, o_key: IntArray, o_free: IntArray, n_rough: int, rough_rows: IntArray
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


def _marginal_covariances(
    J: sp.csr_matrix, weights: FloatArray, lay: _Layout
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


def _independent_views(positions: FloatArray, spacing_m: float) -> int:
    """Views (robot positions in time order) at least `spacing_m` from the last counted one."""
    count, last = 0, None
    for p in positions:
        if last is None or float(np.hypot(*(p - last))) >= spacing_m:
            count += 1
            last = p
    return count


def _result(
    problem: SurveyProblem,
    cfg: BundleConfig,
    anchors: dict[int, FloatArray],
    fit: _Fit,
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
    cov_lm, _ = _marginal_covariances(fit.jac, weights, lay)
    rough = {int(k): np.asarray(v) for k, v in problem.given.items() if v is not None}
    obs = problem.observations
    out: dict[int, LandmarkEstimate] = {}
    for lid in sorted(set(lay.free_ids) | set(anchors)):
        rows = np.flatnonzero(fit.o_id == lid)
        e = fit.err[rows][fit.valid[rows]]
        views = _independent_views(poses[fit.o_key[rows], :2], cfg.independent_view_m)
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
