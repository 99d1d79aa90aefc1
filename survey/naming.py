"""Between the survey's windows: tracks the solution cannot explain are set aside
(`outlier_tracks`), tracks not in use yet are named where the solution agrees
(`name_by_geometry`). docs/survey.md."""

from __future__ import annotations

import numpy as np

from localizer.types import BoolArray, FloatArray, IntArray
from survey.ceiling import ceiling_points_world
from survey.layout import Fit
from survey.problem import BundleConfig, SurveyProblem


def name_by_geometry(
    problem: SurveyProblem,
    cfg: BundleConfig,
    fit: Fit,
    labels: IntArray,
    in_window: BoolArray,
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


def outlier_tracks(fit: Fit, limit_px: float) -> set[int]:
    """Tracks whose median reprojection error exceeds `limit_px` and five times the typical
    track's (a solution that has not settled yet explains nothing well: it rejects nothing).
    """
    if len(fit.o_track) == 0:
        return set()
    err = np.where(fit.valid, fit.err, np.inf)
    order = np.argsort(fit.o_track, kind="stable")
    tracks, starts = np.unique(fit.o_track[order], return_index=True)
    medians = np.array([float(np.median(e)) for e in np.split(err[order], starts[1:])])
    if len(medians) == 0:
        return set()
    bar = max(limit_px, 5.0 * float(np.median(medians)))
    return {int(t) for t, m in zip(tracks.tolist(), medians.tolist(), strict=True) if m > bar}
