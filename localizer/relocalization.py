"""Re-localization without LEDs: map-consistent data association over pose hypotheses.

When the localizer is lost (or has dead-reckoned long enough that the prediction cannot be
trusted to pair spots with landmarks) and cannot, or need not, blink LEDs, the spots of one
frame are matched to the map as a whole:

1. every spot's ray is intersected with the ceiling (the map's median landmark height) in the
   body frame (`handoff.ceiling_points_body`);
2. *hypotheses*: a pair of spots near the image centre (the most accurate, least distorted)
   whose ceiling distance matches the map distance of a pair of landmarks, in either order,
   gives a planar pose (2D rigid registration of two points, eqs. 1-2); hypotheses outside
   the prior's gate are dropped;
3. *scoring by every spot*: each hypothesis carries all the frame's ceiling points into the
   world; a spot is an inlier when a landmark lies within a tolerance that grows with its
   distance from the camera (a wrong ceiling height moves far points most). The score is a
   log-likelihood ratio: `inlier_log_lr` per inlier minus half the prior's squared
   Mahalanobis distance; each hypothesis, refit to its inliers, also loses `miss_log_lr`
   for every lit landmark they place well inside the image (`miss_margin_px` from its edge) with no
   spot near it (a grid shifted by one spacing explains the same spots, but puts a row of
   landmarks where the image shows none);
4. the best hypothesis is accepted only when it is *unambiguous*: enough inliers, and every
   distinct hypothesis (farther than `distinct_m` or `distinct_rad`) scores at least
   `margin` lower. On a regular grid one spacing apart scores the same from the spots alone:
   only the prior can separate them, and when it cannot the answer is "no fix" (stay lost)
   rather than a guess.

The accepted hypothesis returns its (map row, spot) pairs, to be solved and fused as any fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import wrap_angle
from localizer.handoff import ceiling_points_body

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class RelocalizationConfig:
    """Tuning of `relocalize`.

    Attributes:
        every_s: the localizer tries at most this often, seconds (0: every frame).
        anchor_spots: the spots nearest the image centre that form hypothesis pairs.
        score_spots: the hypotheses are scored on this many spots nearest the centre.
        rescore_chunk: hypotheses rescored with their missing landmarks at a time.
        distance_tolerance_m: a spot pair's ceiling distance must match a landmark pair's
            within this (plus `distance_tolerance_frac` of the distance), metres.
        distance_tolerance_frac: relative part of that tolerance.
        inlier_tolerance_m: a spot is an inlier of a hypothesis when a landmark lies within
            this of its ceiling point, metres, plus `inlier_tolerance_per_m` per metre of
            the point's horizontal distance from the camera.
        inlier_tolerance_per_m: that growth (uneven ceilings, lens error at the edge).
        inlier_log_lr: log-likelihood ratio of one inlier (a landmark where a spot says).
        min_inliers: fewest inliers to accept a hypothesis.
        min_inlier_fraction: fewest inliers as a fraction of the spots in view.
        margin: the best hypothesis must score this much more than any distinct one
            (log-likelihood; 9 is about 8000:1).
        distinct_m: hypotheses farther apart than this are distinct, metres.
        distinct_rad: or whose headings differ by more than this, radians.
        prior_gate_chi2: hypotheses beyond this squared Mahalanobis distance from the prior
            are not scored (3 dof; 25 is far out in the tail).
        max_hypotheses: at most this many hypotheses are scored (the nearest the prior).
        miss_log_lr: log-likelihood ratio against a hypothesis per such missing landmark
            (small: a dead LED or a person also hides one).
        miss_margin_px: only landmarks predicted this far inside the image count.
        miss_radius_px: a landmark is missing when no spot lies within this of it, pixels.
    """

    every_s: float = 0.2
    anchor_spots: int = 3
    score_spots: int = 80
    rescore_chunk: int = 32
    distance_tolerance_m: float = 0.03
    distance_tolerance_frac: float = 0.03
    inlier_tolerance_m: float = 0.03
    inlier_tolerance_per_m: float = 0.05
    inlier_log_lr: float = 3.0
    min_inliers: int = 4
    min_inlier_fraction: float = 0.5
    margin: float = 9.0
    distinct_m: float = 0.08
    distinct_rad: float = 0.1
    prior_gate_chi2: float = 25.0
    max_hypotheses: int = 3000
    miss_log_lr: float = 1.5
    miss_margin_px: float = 25.0
    miss_radius_px: float = 12.0


@dataclass(frozen=True)
class Relocalization:
    """The outcome of `relocalize`.

    Attributes:
        pose: the best hypothesis's pose (x, y, theta), or None when there was none.
        pairs: its (map row, spot index) inliers, when accepted; empty otherwise.
        score, second: the best score and the best distinct other's (-inf: none).
        hypotheses: how many were scored.
    """

    pose: tuple[float, float, float] | None
    pairs: list[tuple[int, int]]
    score: float
    second: float
    hypotheses: int

    @property
    def accepted(self) -> bool:
        return bool(self.pairs)


_NONE = Relocalization(None, [], -math.inf, -math.inf, 0)


def hypotheses_from_anchor_pairs(
    q: FloatArray,
    anchors: list[int],
    P: FloatArray,
    config: RelocalizationConfig,
) -> FloatArray:
    """Planar poses (x, y, theta), shape (H, 3), from anchor spot pairs matched to landmark
    pairs of the same ceiling distance (both orders).

    Args:
        q: ceiling points of the spots, body frame, shape (S, 2).
        anchors: indices into `q` forming the pairs.
        P: landmark positions (x, y), shape (N, 2).
    """
    d_map = np.hypot(P[:, None, 0] - P[None, :, 0], P[:, None, 1] - P[None, :, 1])
    out = []
    for ia in range(len(anchors)):
        for ib in range(ia + 1, len(anchors)):
            a, b = anchors[ia], anchors[ib]
            qa, qb = q[a], q[b]
            d = float(np.hypot(*(qb - qa)))
            tol = config.distance_tolerance_m + config.distance_tolerance_frac * d
            i, k = np.nonzero(np.abs(d_map - d) <= tol)
            keep = i != k
            i, k = i[keep], k[keep]
            if len(i) == 0:
                continue
            # rotation taking the body vector qb - qa onto the world vector P_k - P_i
            ang_b = math.atan2(qb[1] - qa[1], qb[0] - qa[0])
            ang_w = np.arctan2(P[k, 1] - P[i, 1], P[k, 0] - P[i, 0])
            th = ang_w - ang_b
            c, s = np.cos(th), np.sin(th)
            mid_q = 0.5 * (qa + qb)
            mid_P = 0.5 * (P[i] + P[k])
            x = mid_P[:, 0] - (c * mid_q[0] - s * mid_q[1])
            y = mid_P[:, 1] - (s * mid_q[0] + c * mid_q[1])
            out.append(np.column_stack([x, y, wrap_angle(th)]))
    return np.vstack(out) if out else np.zeros((0, 3))


def score_hypotheses(
    hyps: FloatArray,
    q: FloatArray,
    radial_m: FloatArray,
    tree: cKDTree,
    config: RelocalizationConfig,
) -> tuple[FloatArray, npt.NDArray[np.int64], npt.NDArray[np.int64]]:
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
) -> FloatArray:
    """Per hypothesis, the landmarks it predicts well inside the image with no spot near
    (all hypotheses projected in one call)."""
    H, N = len(hyps), len(positions)
    c, s = np.cos(hyps[:, 2]), np.sin(hyps[:, 2])
    dx = positions[None, :, 0] - hyps[:, 0, None]
    dy = positions[None, :, 1] - hyps[:, 1, None]
    body = np.stack([c[:, None] * dx + s[:, None] * dy, -s[:, None] * dx + c[:, None] * dy,
                     np.broadcast_to(positions[None, :, 2], (H, N))], axis=-1)  # fmt: skip
    T = camera.T_camera_body
    p_cam = body.reshape(-1, 3) @ T[:3, :3].T + T[:3, 3]
    px, valid = pixels_from_points_camera(camera, p_cam)
    m = config.miss_margin_px
    inner = valid & (px[:, 0] >= m) & (px[:, 0] <= camera.width - 1 - m)
    inner &= (px[:, 1] >= m) & (px[:, 1] <= camera.height - 1 - m)
    # only as far out as spots are seen at all (far spots fade below the threshold)
    spots = spot_tree.data
    r_seen = float(np.max(np.hypot(spots[:, 0] - camera.cu, spots[:, 1] - camera.cv)))
    inner &= np.hypot(px[:, 0] - camera.cu, px[:, 1] - camera.cv) <= r_seen - m
    miss = np.zeros(H * N, dtype=bool)
    if np.any(inner):
        dist, _ = spot_tree.query(px[inner])
        miss[np.nonzero(inner)[0]] = dist > config.miss_radius_px
    out: FloatArray = miss.reshape(H, N).sum(axis=1).astype(np.float64)
    return out


def refine_hypotheses(
    hyps: FloatArray, q: FloatArray, P: FloatArray, nearest: npt.NDArray[np.int64],
    inl: npt.NDArray[np.int64],
) -> FloatArray:  # fmt: skip
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


def relocalize(
    camera: CameraModel,
    positions: FloatArray,
    spot_pixels: FloatArray,
    prior: tuple[float, float, float],
    prior_covariance: FloatArray,
    config: RelocalizationConfig,
) -> Relocalization:
    """Map-consistent data association over pose hypotheses (see the module docstring).

    Args:
        positions: landmark positions (of the lit ones only, when LEDs are known dark),
            shape (N, 3).
        spot_pixels: the frame's spots, shape (S, 2).
        prior: the pose thought most likely (dead reckoning).
        prior_covariance: its covariance, shape (3, 3) (widen it for a kidnapped robot).

    Returns:
        The outcome; `pairs` is empty unless accepted.
    """
    S, N = len(spot_pixels), len(positions)
    if S < 2 or N < 2:
        return _NONE
    z = float(np.median(positions[:, 2]))
    q = ceiling_points_body(camera, spot_pixels, np.full(S, z))
    ok = np.all(np.isfinite(q), axis=1)
    if np.count_nonzero(ok) < 2:
        return _NONE
    centre = np.array([camera.cu, camera.cv])
    r_px = np.hypot(*(spot_pixels - centre).T)
    order_all = [int(i) for i in np.argsort(r_px) if ok[i]]
    anchors = order_all[: config.anchor_spots]
    P = positions[:, :2]
    hyps = hypotheses_from_anchor_pairs(q, anchors, P, config)
    if len(hyps) == 0:
        return _NONE
    try:
        info = np.linalg.inv(np.asarray(prior_covariance, dtype=np.float64))
    except np.linalg.LinAlgError:
        return _NONE
    d = hyps - np.asarray(prior)
    d[:, 2] = wrap_angle(d[:, 2])
    m2 = np.einsum("hi,ij,hj->h", d, info, d)
    gate = m2 <= config.prior_gate_chi2
    hyps, m2 = hyps[gate], m2[gate]
    if len(hyps) == 0:
        return _NONE
    # one hypothesis per pose (the anchor pairs find the same one several times)
    order = np.argsort(m2, kind="stable")[: config.max_hypotheses]
    cell = np.column_stack([
        np.round(hyps[order, 0] / config.distinct_m), np.round(hyps[order, 1] / config.distinct_m),
        np.round(wrap_angle(hyps[order, 2]) / config.distinct_rad),
    ])  # fmt: skip
    _, first = np.unique(cell, axis=0, return_index=True)
    keep = order[np.sort(first)]
    hyps, m2 = hyps[keep], m2[keep]
    qv = np.where(ok[:, None], q, 1e6)  # spots without a ceiling point match nothing
    cam_xy = camera.T_body_camera[:2, 3]
    radial_m = np.where(ok, np.hypot(*(q - cam_xy).T), 0.0)
    sub = np.array(order_all[: config.score_spots])
    tree = cKDTree(P)
    counts, nearest, inl = score_hypotheses(hyps, qv[sub], radial_m[sub], tree, config)
    score = config.inlier_log_lr * counts - 0.5 * m2
    # Rescore with the missing landmarks, best first, until no other can come within the
    # margin (misses only lower a score: the rest keep theirs as an upper bound).
    spot_tree = cKDTree(spot_pixels)
    done = np.zeros(len(hyps), dtype=bool)
    ranked = np.argsort(-score, kind="stable")
    chunk = config.rescore_chunk
    for k in range(0, len(ranked), chunk):
        idx = ranked[k : k + chunk]
        best_now = float(np.max(score[done])) if np.any(done) else -math.inf
        if score[idx[0]] < best_now - config.margin:
            break
        hyps[idx] = refine_hypotheses(hyps[idx], qv[sub], P, nearest[idx], inl[idx])
        score[idx] -= config.miss_log_lr * missing_landmarks(
            camera, positions, hyps[idx], spot_tree, config
        )
        done[idx] = True
    best = int(np.argmax(np.where(done, score, -math.inf)))
    bx, by, bt = hyps[best]
    far = (np.hypot(hyps[:, 0] - bx, hyps[:, 1] - by) > config.distinct_m) | (
        np.abs(wrap_angle(hyps[:, 2] - bt)) > config.distinct_rad
    )
    second = float(np.max(score[far])) if np.any(far) else -math.inf
    pose = (float(bx), float(by), float(bt))
    out = Relocalization(pose, [], float(score[best]), second, len(hyps))
    n_in = int(counts[best])
    if n_in < max(config.min_inliers, config.min_inlier_fraction * len(sub)):
        return out
    if score[best] - second < config.margin:
        return out
    _, nearest_all, inl_all = score_hypotheses(hyps[best : best + 1], qv, radial_m, tree, config)
    nearest, inl = nearest_all, inl_all
    best = 0
    # one spot per landmark: the nearest of the spots that chose it
    pairs: dict[int, int] = {}
    for j in np.nonzero(inl[best])[0]:
        row = int(nearest[best, j])
        pairs.setdefault(row, int(j))
    return Relocalization(pose, sorted(pairs.items()), out.score, second, len(hyps))
