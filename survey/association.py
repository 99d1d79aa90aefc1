"""Naming spot tracks without blinks: map-consistent association along the drive.

Between the survey's windows (`survey.bundle`), tracks no blink named are named from where
they sit, as the localizer's hand-off names a new spot by its predicted pixel, but over the
whole drive at once and never from one frame:

1. **Where each track is** (`track_points`): its spots put on the ceiling from the solved
   poses; its point is the median of its most vertical sightings; its covariance the
   keyframe pose's marginal covariance (`BandedSchur.banded_covariance_blocks`) carried to
   the point, plus what the unknown height leaves off-axis.
2. **Which tracks are one landmark** (`cluster_tracks`): tracks join a cluster when their
   points agree within the gate and they were never in one frame together (one landmark
   makes one spot a frame). A cluster needs `min_views` independent views to be named.
3. **Which landmark each cluster is** (`assign`): every cluster against every landmark of
   the map at once, one to one (`scipy.optimize.linear_sum_assignment` on Mahalanobis
   distances, gated): landmarks placed already at their estimate and covariance, the others
   at their rough position with its sigma. A pairing stands only if every alternative that
   gives its cluster another landmark, or its landmark another cluster, costs `margin_chi2`
   more (odds of e^(margin / 2) to one): swapped neighbours and landmarks closer together
   than their rough positions can tell apart stay unnamed, with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from localizer.camera import predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.types import BoolArray, FloatArray, IntArray
from survey.ceiling import ceiling_points_world
from survey.estimates import independent_views, weighted_information
from survey.layout import Fit
from survey.problem import BundleConfig, SurveyProblem

_FAR = 1e6


@dataclass(eq=False)
class SpotCluster:
    """Spot tracks taken for one landmark: their point (x, y) and its covariance (2, 2)."""

    tracks: list[int]
    point: FloatArray
    cov: FloatArray
    frames: set[int] = field(default_factory=set)
    xy: list[FloatArray] = field(default_factory=list)  # robot positions that saw it
    t: list[int] = field(default_factory=list)  # their keyframes (time order)


@dataclass(frozen=True)
class TrackPoint:
    """One track on the ceiling: point (2,), covariance (2, 2), its keyframes and frames."""

    point: FloatArray
    cov: FloatArray
    keys: IntArray
    frames: frozenset[int]


def _chi2(d: FloatArray, S: FloatArray) -> float:
    return float(d @ np.linalg.solve(S, d))


def track_points(
    problem: SurveyProblem,
    fit: Fit,
    pose_cov: FloatArray,
    rows: IntArray,
    frame_key: IntArray,
    z_m: float,
    height_sigma_m: float,
) -> dict[int, TrackPoint]:
    """Each track's point on the ceiling (plane `z_m`) from the solved poses.

    Args:
        pose_cov: the marginal covariance of every keyframe pose, shape (K, 3, 3).
        rows: observations to use (unnamed, at keyframes); frame_key: keyframe of each
            observation's frame (-1 none), shape (M,).
        height_sigma_m: how far a landmark's height may be from `z_m` (1 sigma): off-axis it
            moves the point radially by that times the ray's slope.
    """
    obs = problem.observations
    poses = fit.poses()
    keys = frame_key[rows]
    q, hit = ceiling_points_world(problem.camera, poses[keys], obs.pixels[rows], z_m)
    origin_z = float(problem.camera.T_body_camera[2, 3])
    out: dict[int, TrackPoint] = {}
    order = np.argsort(obs.track[rows], kind="stable")
    tracks, starts = np.unique(obs.track[rows][order], return_index=True)
    for tr, sel in zip(tracks.tolist(), np.split(order, starts[1:]), strict=True):
        sel = sel[hit[sel]]
        if len(sel) == 0:
            continue
        off = np.hypot(*(q[sel, :2] - poses[keys[sel], :2]).T)
        near = sel[off <= off.min() + 0.25]
        point = np.median(q[near, :2], axis=0)
        k = int(keys[sel[int(np.argmin(off))]])
        d = point - poses[k, :2]
        Jp = np.array([[1.0, 0.0, -d[1]], [0.0, 1.0, d[0]]])
        r = float(np.hypot(*d))
        u = d / r if r > 1e-9 else np.zeros(2)
        slope = r / max(z_m - origin_z, 0.1)
        cov = Jp @ pose_cov[k] @ Jp.T + (height_sigma_m * slope) ** 2 * np.outer(u, u)
        cov += (0.005**2) * np.eye(2)  # the median of a few noisy rays
        out[int(tr)] = TrackPoint(
            point, cov, np.unique(keys[sel]), frozenset(obs.frame[rows][sel].tolist())
        )
    return out


def cluster_tracks(
    points: dict[int, TrackPoint], poses: FloatArray, gate_chi2: float
) -> list[SpotCluster]:
    """Tracks grouped by landmark, best-placed first: a track joins the one cluster whose
    point agrees with its own within `gate_chi2` and that it never shared a frame with; a
    track that two clusters could take joins none."""
    clusters: list[SpotCluster] = []
    for tr in sorted(points, key=lambda t: float(np.trace(points[t].cov))):
        tp = points[tr]
        fits = [
            c
            for c in clusters
            if c.frames.isdisjoint(tp.frames)
            and _chi2(tp.point - c.point, tp.cov + c.cov) <= gate_chi2
        ]
        if len(fits) > 1:
            continue
        if fits:
            c = fits[0]
            info = np.linalg.inv(c.cov) + np.linalg.inv(tp.cov)
            c.point = np.linalg.solve(
                info, np.linalg.solve(c.cov, c.point) + np.linalg.solve(tp.cov, tp.point)
            )
            # the tracks' errors are mostly the poses', shared along the drive: keep the best
            c.cov = c.cov if np.trace(c.cov) <= np.trace(tp.cov) else tp.cov
        else:
            c = SpotCluster([], tp.point.copy(), tp.cov.copy())
            clusters.append(c)
        c.tracks.append(tr)
        c.frames |= tp.frames
        c.t.extend(tp.keys.tolist())
    for c in clusters:
        ks = np.unique(np.asarray(c.t, dtype=np.int64))
        c.t = ks.tolist()
        c.xy = [poses[k, :2] for k in ks.tolist()]
    return clusters


def assign(
    points: FloatArray,
    point_covs: FloatArray,
    entry_of: list[int],
    entry_xy: FloatArray,
    entry_covs: FloatArray,
    gate_chi2: float,
    margin_chi2: float,
) -> tuple[dict[int, int], dict[int, set[int]]]:
    """Clusters to map entries, one to one, where no alternative comes close.

    Args:
        points, point_covs: the clusters' points (C, 2) and covariances (C, 2, 2).
        entry_of: each column's landmark (a landmark placed already may have several
            columns: spots of one landmark that did not merge), length E.
        entry_xy, entry_covs: each column's position (E, 2) and covariance (E, 2, 2).
        gate_chi2: a pairing beyond this Mahalanobis^2 is impossible; a cluster left without
            a pairing costs this (it is no landmark of the map).
        margin_chi2: how much more the best alternative must cost.

    Returns:
        (cluster -> landmark for the pairings that stand, landmark -> the landmarks its
        clusters could also be, for those that do not).
    """
    C, E = len(points), len(entry_of)
    if C == 0 or E == 0:
        return {}, {}
    cost = np.full((C, E), _FAR)
    for i in range(C):
        for j in range(E):
            d2 = _chi2(points[i] - entry_xy[j], point_covs[i] + entry_covs[j])
            if d2 <= gate_chi2:
                cost[i, j] = d2
    # square problem: cluster -> no entry costs the gate, an entry may stay unseen for free
    n = C + E
    full = np.full((n, n), _FAR)
    full[:C, :E] = cost
    full[:C, E:] = np.where(np.eye(C, dtype=bool), gate_chi2, _FAR)
    full[C:, :E] = np.where(np.eye(E, dtype=bool), 0.0, _FAR)
    full[C:, E:] = 0.0

    def solve(m: FloatArray) -> tuple[float, dict[int, int]]:
        r, c = linear_sum_assignment(m)
        pairs = {int(a): int(b) for a, b in zip(r, c, strict=True) if a < C and b < E}
        return float(m[r, c].sum()), pairs

    best, pairs = solve(full)
    named: dict[int, int] = {}
    doubt: dict[int, set[int]] = {}
    for i, j in pairs.items():
        lid = entry_of[j]
        same = [k for k in range(E) if entry_of[k] == lid]
        rivals: set[int] = set()
        ok = True
        for force in ("cluster", "entry"):
            m = full.copy()
            m[i, same] = _FAR
            if force == "cluster":  # the cluster must be another landmark
                m[i, E + i] = _FAR
            else:  # the landmark must be another cluster
                for k in same:
                    m[C + k, k] = _FAR
            alt, alt_pairs = solve(m)
            if alt >= _FAR:
                continue  # no such alternative at all
            if alt - best < margin_chi2:
                ok = False  # the landmarks whose pairing the alternative changes
                moved = set(pairs.items()) ^ set(alt_pairs.items())
                rivals |= {entry_of[b] for _, b in moved}
        if ok:
            named[i] = lid
        else:
            doubt.setdefault(lid, set()).update(rivals - {lid})
    return named, doubt


def name_by_association(
    problem: SurveyProblem,
    cfg: BundleConfig,
    fit: Fit,
    labels: IntArray,
    in_window: BoolArray,
    rejected: set[int],
    z_m: float,
) -> tuple[int, dict[int, set[int]]]:
    """Name the tracks not in use yet by map-consistent association (in place).

    Returns:
        (how many tracks were named, landmark -> the neighbours it could not be told from).
    """
    obs = problem.observations
    key_index = {int(t): k for k, t in enumerate(fit.key_t.tolist())}
    frame_key = np.array(
        [key_index.get(int(t), -1) for t in problem.frame_t_ns[obs.frame].tolist()],
        dtype=np.int64,
    )
    todo = np.flatnonzero(
        (labels < 0) & in_window & (frame_key >= 0) & ~np.isin(obs.track, list(rejected))
    )
    if len(todo) == 0:
        return 0, {}
    info, _ = weighted_information(fit, cfg.huber_scale)
    keys = np.unique(frame_key[todo])
    pose_cov = np.zeros((fit.lay.n_keys, 3, 3))
    pose_cov[keys] = info.banded_covariance_blocks(keys)
    points = track_points(problem, fit, pose_cov, todo, frame_key, z_m, cfg.ceiling_sigma_m)
    poses = fit.poses()
    clusters = [
        c
        for c in cluster_tracks(points, poses, cfg.association_gate_chi2)
        if independent_views(np.array(c.xy), cfg.independent_view_m) >= cfg.min_views
    ]
    if not clusters:
        return 0, {}
    pts = np.array([c.point for c in clusters])
    pcov = np.array([c.cov for c in clusters])
    lm_cov = info.reduced_covariance()
    entry_of: list[int] = []
    entry_xy: list[FloatArray] = []
    entry_cov: list[FloatArray] = []
    for lid, p in fit.landmarks().items():  # placed already: as many columns as may be it
        i = fit.lay.free_index[lid]
        cov = lm_cov[3 * i : 3 * i + 2, 3 * i : 3 * i + 2]
        near = sum(
            1 for c in clusters if _chi2(c.point - p[:2], c.cov + cov) <= cfg.association_gate_chi2
        )
        for _ in range(max(near, 1)):
            entry_of.append(lid)
            entry_xy.append(p[:2])
            entry_cov.append(cov)
    placed = set(fit.lay.free_ids)
    for lid, g in problem.given.items():
        if g is not None and lid not in placed:
            entry_of.append(int(lid))
            entry_xy.append(np.asarray(g, dtype=np.float64)[:2])
            entry_cov.append(cfg.rough_sigma_m**2 * np.eye(2))
    named, doubt = assign(
        pts,
        pcov,
        entry_of,
        np.array(entry_xy).reshape(-1, 2),
        np.array(entry_cov).reshape(-1, 2, 2),
        cfg.association_gate_chi2,
        cfg.association_margin_chi2,
    )
    count = 0
    for i, lid in named.items():
        rows = np.isin(obs.track, clusters[i].tracks)
        labels[rows & (labels < 0)] = lid
        count += len(clusters[i].tracks)
    return count, doubt


def unnamed_reasons(
    problem: SurveyProblem,
    cfg: BundleConfig,
    fit: Fit,
    labels: IntArray,
    placed: set[int],
    doubt: dict[int, set[int]],
) -> dict[int, str]:
    """Why each landmark of the map that the survey did not place was not: too close to a
    neighbour for its rough position, never in view, no position and no blink, or too few
    views."""
    out: dict[int, str] = {}
    cam = problem.camera
    poses = fit.poses()
    seen = {int(i) for i in np.unique(labels) if i >= 0}
    for lid, g in sorted(problem.given.items()):
        if lid in placed:
            continue
        if lid in seen:
            out[lid] = (
                f"seen from fewer than {cfg.min_views} places {cfg.independent_view_m} m "
                "apart: drive under it"
            )
        elif g is None:
            out[lid] = "no position in map.json and no blink named its spots"
        elif lid in doubt:
            near = ", ".join(
                f"{r} ({100 * float(np.hypot(*(_where(problem, fit, r, g) - g[:2]))):.0f} cm)"
                for r in sorted(doubt[lid])
            )
            out[lid] = (
                f"too close to a neighbour for its rough position (sigma "
                f"{100 * cfg.rough_sigma_m:.0f} cm): its spots could be {near or 'another'}'s; "
                "blink it or give its position more precisely"
            )
        else:
            in_view = False
            for pose in poses[:: max(1, len(poses) // 400)]:
                px, ok = predict_pixels(cam, T_world_body_from_pose(*pose), g[None, :])
                if ok[0] and 0 <= px[0, 0] < cam.width and 0 <= px[0, 1] < cam.height:
                    in_view = True
                    break
            out[lid] = (
                "in view at its map position, but no spots there agree with it (LED dark, "
                "or its position off by more than the rough sigma allows)"
                if in_view
                else "never in view of the drive (at its map position)"
            )
    return out


def _where(problem: SurveyProblem, fit: Fit, lid: int, default: FloatArray) -> FloatArray:
    """A landmark's x, y as the association saw it: estimated, else rough, else `default`."""
    placed = fit.landmarks()
    if lid in placed:
        return placed[lid][:2]
    g = problem.given.get(lid)
    return np.asarray(default if g is None else g, dtype=np.float64)[:2]
