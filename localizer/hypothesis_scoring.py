"""Scoring pose hypotheses against one frame: every spot for a hypothesis, every landmark it
predicts where the image shows none against it (`relocalization` step 3).

A frame's spots become ceiling points in the body frame (`frame_view`); each hypothesis
(x, y, theta) carries them into the world, where a spot is an inlier when a landmark lies
within a tolerance growing with its distance from the camera (`score_hypotheses`); the
hypothesis is refit to its inliers (`refine_hypotheses`, 2D rigid registration); the
landmarks it places well inside the image, within the radius spots are seen at all, with no
spot near count against it (`missing_landmarks`). `frame_log_lr` puts these together as a
log-likelihood ratio per hypothesis. All vectorised over the hypotheses.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import wrap_angle
from localizer.handoff import ceiling_points_body
from localizer.types import BoolArray, FloatArray, IntArray

if TYPE_CHECKING:
    from localizer.relocalization import RelocalizationConfig


def score_hypotheses(
    hyps: FloatArray,
    q: FloatArray,
    radial_m: FloatArray,
    tree: cKDTree,
    config: RelocalizationConfig,
) -> tuple[FloatArray, IntArray, IntArray]:
    """Inliers of each hypothesis: every spot's ceiling point carried into the world and
    matched to its nearest landmark.

    Returns:
        (inlier counts shape (H,), nearest landmark row per (hypothesis, spot) shape (H, S),
        inlier mask as 0/1 shape (H, S)).
    """
    c, s = np.cos(hyps[:, 2]), np.sin(hyps[:, 2])
    wx = hyps[:, 0, None] + c[:, None] * q[None, :, 0] - s[:, None] * q[None, :, 1]
    wy = hyps[:, 1, None] + s[:, None] * q[None, :, 0] + c[:, None] * q[None, :, 1]
    dist, nearest = tree.query(np.column_stack([wx.ravel(), wy.ravel()]))
    tol = config.inlier_tolerance_m + config.inlier_tolerance_per_m * radial_m
    inl = (dist.reshape(wx.shape) <= tol[None, :]).astype(np.int64)
    return inl.sum(axis=1).astype(np.float64), nearest.reshape(wx.shape), inl


def missing_landmarks(
    camera: CameraModel,
    positions: FloatArray,
    hyps: FloatArray,
    spot_tree: cKDTree,
    config: RelocalizationConfig,
    *,
    reach_m: float | None = None,
    counted: BoolArray | None = None,
    weights: FloatArray | None = None,
) -> FloatArray:
    """Per hypothesis, the landmarks it predicts well inside the image with no spot near
    (all hypotheses projected in one call): negative evidence, each landmark weighted by
    the log-likelihood ratio of its absence (`weights`, shape (N,); default 1: a count).

    Args:
        reach_m: when given, only the landmarks within this of each hypothesis's camera
            (horizontally) are projected (those farther out lie beyond the farthest spot).
        counted: (H, N) whether each landmark has already counted as missing against each
            hypothesis (on an earlier frame): those are not counted again, and the new ones
            are marked (updated in place). A dead LED is the same evidence on every frame.

    Returns:
        The (weighted) count per hypothesis, shape (H,).
    """
    H, N = len(hyps), len(positions)
    c, s = np.cos(hyps[:, 2]), np.sin(hyps[:, 2])
    dx = positions[None, :, 0] - hyps[:, 0, None]
    dy = positions[None, :, 1] - hyps[:, 1, None]
    bx, by = c[:, None] * dx + s[:, None] * dy, -s[:, None] * dx + c[:, None] * dy  # (H, N)
    if reach_m is None:
        h, rows = np.nonzero(np.ones((H, N), dtype=bool))
    else:
        cb = camera.T_body_camera[:2, 3]
        h, rows = np.nonzero(np.hypot(bx - cb[0], by - cb[1]) <= reach_m)
    if not len(h):
        return np.zeros(H)
    body = np.column_stack([bx[h, rows], by[h, rows], positions[rows, 2]])
    T = camera.T_camera_body
    px, valid = pixels_from_points_camera(camera, body @ T[:3, :3].T + T[:3, 3])
    inner = well_in_view(camera, px, valid, seen_radius_px(camera, spot_tree.data), config)
    miss = np.zeros(len(h), dtype=bool)
    if np.any(inner):
        dist, _ = spot_tree.query(px[inner])
        miss[np.nonzero(inner)[0]] = dist > config.miss_radius_px
    if counted is not None:
        miss &= ~counted[h, rows]
        counted[h[miss], rows[miss]] = True
    w = np.ones(N) if weights is None else weights
    out: FloatArray = np.bincount(h, weights=miss * w[rows], minlength=H).astype(np.float64)
    return out


def seen_radius_px(camera: CameraModel, pixels: FloatArray) -> float:
    """How far from the image centre spots are seen at all on a frame (the farthest of
    `pixels`, shape (S, 2)): beyond it a landmark's spot fades below the threshold, pixels."""
    if not len(pixels):
        return 0.0
    return float(np.max(np.hypot(pixels[:, 0] - camera.cu, pixels[:, 1] - camera.cv)))


def well_in_view(
    camera: CameraModel,
    px: FloatArray,
    valid: BoolArray,
    r_seen_px: float,
    config: RelocalizationConfig,
) -> BoolArray:
    """Which predicted pixels (N, 2) lie well inside the image: valid, `miss_margin_px`
    from its edges and from the radius `r_seen_px` spots are seen at all on this frame.
    A lit landmark predicted there should be detected (its absence is evidence)."""
    m = config.miss_margin_px
    inner = valid & (px[:, 0] >= m) & (px[:, 0] <= camera.width - 1 - m)
    inner &= (px[:, 1] >= m) & (px[:, 1] <= camera.height - 1 - m)
    inner &= np.hypot(px[:, 0] - camera.cu, px[:, 1] - camera.cv) <= r_seen_px - m
    out: BoolArray = inner
    return out


def refine_hypotheses(
    hyps: FloatArray, q: FloatArray, P: FloatArray, nearest: IntArray, inl: IntArray
) -> FloatArray:
    """Each hypothesis refit to its inliers (weighted 2D rigid registration, all at once):
    a pose from two points leaves the heading rough."""
    w = inl.astype(np.float64)
    n = w.sum(axis=1)
    ok = n >= 3
    if not np.any(ok):
        return hyps
    w, nearest = w[ok], nearest[ok]
    n = n[ok][:, None]
    Pm = P[nearest]  # (H, S, 2)
    qc = (w[..., None] * q[None]).sum(axis=1) / n
    pc = (w[..., None] * Pm).sum(axis=1) / n
    a = q[None] - qc[:, None]
    b = Pm - pc[:, None]
    dot = (w * (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1])).sum(axis=1)
    cross = (w * (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])).sum(axis=1)
    th = np.arctan2(cross, dot)
    c, s = np.cos(th), np.sin(th)
    out = hyps.copy()
    out[ok, 0] = pc[:, 0] - (c * qc[:, 0] - s * qc[:, 1])
    out[ok, 1] = pc[:, 1] - (s * qc[:, 0] + c * qc[:, 1])
    out[ok, 2] = wrap_angle(th)
    return out


class FrameView(NamedTuple):
    """One frame's spots prepared for scoring hypotheses against a map (`frame_view`).

    Attributes:
        positions: the landmarks, shape (N, 3).
        pixels: the spots, shape (S, 2).
        q: their ceiling points, body frame, shape (S, 2) (far off where a ray misses).
        radial_m: each ceiling point's horizontal distance from the camera, metres, (S,).
        sub: the spots scored (the `score_spots` nearest the image centre), indices.
        anchors: the spots forming hypothesis pairs (the `anchor_spots` nearest the centre).
        landmark_tree: k-d tree of the landmarks' (x, y).
        spot_tree: k-d tree of the spots' pixels.
        miss_weights: each landmark's log-likelihood ratio against a hypothesis that
            predicts it well in view where no spot is, shape (N,) (`landmark_liveness`).
    """

    positions: FloatArray
    pixels: FloatArray
    q: FloatArray
    radial_m: FloatArray
    sub: IntArray
    anchors: list[int]
    landmark_tree: cKDTree
    spot_tree: cKDTree
    miss_weights: FloatArray


def frame_view(
    camera: CameraModel,
    positions: FloatArray,
    spot_pixels: FloatArray,
    config: RelocalizationConfig,
    miss_weights: FloatArray | None = None,
) -> FrameView | None:
    """The frame's spots as ceiling points (see `FrameView`); None with fewer than two
    usable spots or landmarks. `miss_weights` (N,) defaults to `config.miss_log_lr` each
    (nothing known of any landmark)."""
    S = len(spot_pixels)
    if S < 2 or len(positions) < 2:
        return None
    z = float(np.median(positions[:, 2]))
    q = ceiling_points_body(camera, spot_pixels, np.full(S, z))
    ok = np.all(np.isfinite(q), axis=1)
    if np.count_nonzero(ok) < 2:
        return None
    r_px = np.hypot(spot_pixels[:, 0] - camera.cu, spot_pixels[:, 1] - camera.cv)
    order = [int(i) for i in np.argsort(r_px, kind="stable") if ok[i]]
    cam_xy = camera.T_body_camera[:2, 3]
    radial_m = np.where(ok, np.hypot(q[:, 0] - cam_xy[0], q[:, 1] - cam_xy[1]), 0.0)
    return FrameView(
        positions,
        spot_pixels,
        np.where(ok[:, None], q, 1e6),
        radial_m,
        np.array(order[: config.score_spots], dtype=np.int64),
        order[: config.anchor_spots],
        cKDTree(positions[:, :2]),
        cKDTree(spot_pixels),
        np.full(len(positions), config.miss_log_lr) if miss_weights is None else miss_weights,
    )


def inliers_needed(view: FrameView, config: RelocalizationConfig) -> float:
    """Fewest inliers a hypothesis needs to explain the frame (`min_inliers`, and
    `min_inlier_fraction` of the scored spots)."""
    return max(config.min_inliers, config.min_inlier_fraction * len(view.sub))


def frame_log_lr(
    camera: CameraModel,
    view: FrameView,
    hyps: FloatArray,
    config: RelocalizationConfig,
    *,
    offset: FloatArray | None = None,
    cutoff: float = math.inf,
    refits: int = 2,
    counted: BoolArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
    """Each hypothesis's log-likelihood ratio on one frame (step 3 of the module docstring):
    refit to its inliers, `inlier_log_lr` per inlier minus each missing landmark's weight
    (`view.miss_weights`), plus `offset`.

    The missing landmarks (the costly part) are counted best first, in chunks of
    `rescore_chunk`, until no hypothesis left can come within `cutoff` of the best (misses
    only lower a score: those left keep their inlier score as an upper bound).

    Args:
        hyps: poses, shape (H, 3).
        offset: added to each score (the prior's log density), shape (H,).
        cutoff: log-likelihood below the best past which scores need not be exact.
        refits: refits to the inliers before scoring (2 for poses from two points; 0 for
            poses refit on an earlier frame: scored as they are, then refit for the next).
        counted: the landmarks already counted as missing, per hypothesis, (H, N)
            (`missing_landmarks`; updated in place).

    Returns:
        (refined poses (H, 3), scores (H,), inlier counts (H,), done: whether the score is
        exact (H,)).
    """
    H = len(hyps)
    q, radial = view.q[view.sub], view.radial_m[view.sub]
    P, tree = view.positions[:, :2], view.landmark_tree
    off = np.zeros(H) if offset is None else offset
    reach = float(np.max(radial)) + 0.3  # beyond the farthest spot, nothing counts
    counts, nearest, inl = score_hypotheses(hyps, q, radial, tree, config)
    if refits > 0:
        hyps = refine_hypotheses(hyps, q, P, nearest, inl)
        counts, nearest, inl = score_hypotheses(hyps, q, radial, tree, config)
    score = config.inlier_log_lr * counts + off
    done = np.zeros(H, dtype=bool)
    ranked = np.argsort(-score, kind="stable")
    chunk = config.rescore_chunk if math.isfinite(cutoff) else max(H, 1)
    for k in range(0, H, chunk):
        idx = ranked[k : k + chunk]
        best_now = float(np.max(score[done])) if np.any(done) else -math.inf
        if score[idx[0]] < best_now - cutoff:
            break
        if refits > 1:
            hyps[idx] = refine_hypotheses(hyps[idx], q, P, nearest[idx], inl[idx])
            counts[idx] = score_hypotheses(hyps[idx], q, radial, tree, config)[0]
        sub = None if counted is None else counted[idx]
        misses = missing_landmarks(
            camera,
            view.positions,
            hyps[idx],
            view.spot_tree,
            config,
            reach_m=reach,
            counted=sub,
            weights=view.miss_weights,
        )
        if counted is not None and sub is not None:
            counted[idx] = sub
        score[idx] = config.inlier_log_lr * counts[idx] + off[idx] - misses
        done[idx] = True
    if refits == 0:
        hyps = refine_hypotheses(hyps, q, P, nearest, inl)
    return hyps, score, counts, done


def inlier_pairs(
    view: FrameView, pose: FloatArray, config: RelocalizationConfig
) -> list[tuple[int, int]]:
    """(landmark row, spot index) of every spot the pose explains, one spot per landmark
    (the nearest of the spots that chose it), sorted by row."""
    _, nearest, inl = score_hypotheses(
        np.asarray(pose, dtype=np.float64).reshape(1, 3),
        view.q,
        view.radial_m,
        view.landmark_tree,
        config,
    )
    pairs: dict[int, int] = {}
    for j in np.nonzero(inl[0])[0]:
        pairs.setdefault(int(nearest[0, j]), int(j))
    return sorted(pairs.items())
