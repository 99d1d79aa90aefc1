"""Re-localization without LEDs: map-consistent data association over pose hypotheses.

When the localizer is lost (or has dead-reckoned long enough that the prediction cannot be
trusted to pair spots with landmarks) and cannot, or need not, blink LEDs, the spots of one
frame are matched to the map as a whole:

1. every spot's ray is intersected with the ceiling (the map's median landmark height) in the
   body frame (`handoff.ceiling_points_body`; `hypothesis_scoring.frame_view`);
2. *hypotheses* (`seed_hypotheses`): a pair of spots near the image centre (the most
   accurate, least distorted) whose ceiling distance matches the map distance of a pair of
   landmarks, in either order, gives a planar pose (2D rigid registration of two points,
   eqs. 1-2); hypotheses outside the prior's gate are dropped, duplicates merged;
3. *scoring by every spot* (`hypothesis_scoring.frame_log_lr`): each hypothesis carries all
   the frame's ceiling points into the world; a spot is an inlier when a landmark lies
   within a tolerance that grows with its distance from the camera (a wrong ceiling height
   moves far points most).
   Each hypothesis is refit to its inliers (a pose from two points leaves the heading rough)
   and scored by a log-likelihood ratio: `inlier_log_lr` per inlier minus `miss_log_lr` for
   every lit landmark it places well inside the image (`miss_margin_px` from its edge, within
   the radius spots are seen at all) with no spot near it: *negative evidence* (a grid shifted
   by one spacing explains the same spots, but puts a row of landmarks where the image shows
   none); `relocalize` adds the prior's log density (minus half the squared Mahalanobis
   distance);
4. the best hypothesis is accepted only when it is *unambiguous*: enough inliers, and every
   distinct hypothesis (farther than `distinct_m` or `distinct_rad`) scores at least
   `margin` lower. On a regular grid one spacing apart scores the same from the spots alone:
   only the prior can separate them, and when it cannot the answer is "no fix" (stay lost)
   rather than a guess.

`relocalize` decides on one frame; `hypothesis_set.HypothesisSet` keeps the hypotheses alive
over frames while the robot drives on (each carried by the odometry and scored by every
frame), so an ambiguity resolves as soon as the grid's edge, a gap or a dead landmark comes
into view. The accepted hypothesis returns its (map row, spot) pairs, to be solved and fused
as any fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.camera import CameraModel
from localizer.geometry import wrap_angle
from localizer.hypothesis_scoring import (
    FrameView,
    frame_log_lr,
    frame_view,
    inlier_pairs,
    inliers_needed,
)
from localizer.types import FloatArray, IntArray


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
        dark_prior: probability that a mapped landmark nothing is known of is dark or
            hidden when predicted in view (a dead LED, never installed, behind a lamp, a
            person under it): deliberately pessimistic, so that its absence weighs little
            (`miss_log_lr`, about 1.5).
        dark_after_lit: probability that a landmark seen lit while tracking (this run) is
            dark or hidden now (failed since, a person under it).
        miss_prior: probability that a lit landmark predicted well in view is not detected
            on a frame (a prior: the rate on the tracked frames updates it,
            `landmark_liveness.LandmarkLiveness`).
        miss_prior_weight: that prior's weight, in landmark-frames.
        miss_margin_px: only landmarks predicted this far inside the image count.
        miss_radius_px: a landmark is missing when no spot lies within this of it, pixels.

    Over frames (`hypothesis_set.HypothesisSet`, while lost):
        score_every_s: the live hypotheses are scored at most this often, seconds (they are
            carried by the odometry every frame).
        frame_clip: one frame lowers a hypothesis's score by at most this against the
            frame's best (log-likelihood; one frame spoiled by a person or a glint never
            decides alone).
        prune_below: hypotheses this far below the best are refuted: no longer scored,
            only remembered with the evidence against them (log-likelihood; more than
            `frame_clip`: no single frame refutes).
        max_live: at most this many hypotheses are scored (the best; the others are
            remembered as the refuted are).
        max_retired: at most this many poses no longer scored are remembered.
        sustain_frames: the best must lead every distinct one by `margin` on this many
            scored frames in a row before it is accepted.
        reseed_after_frames: when the best explains too few of the spots (under
            `min_inliers` / `min_inlier_fraction`) on this many scored frames in a row, the
            set has died (the robot was carried off again, or never among them): it is
            seeded afresh from the next frame.
        birth_every_s: this often new hypotheses are seeded from the current frame and
            join the set `margin` below the best (they must earn their lead), seconds.
        retired_as_gap: a retired pose keeps its gap to the best when it was retired,
            rather than its log-likelihood ratio then (on for passive lights,
            `constellation.scoring_config`).
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
    dark_prior: float = 0.2
    dark_after_lit: float = 0.01
    miss_prior: float = 0.02
    miss_prior_weight: float = 50.0
    miss_margin_px: float = 25.0
    miss_radius_px: float = 12.0
    score_every_s: float = 0.2
    frame_clip: float = 15.0
    prune_below: float = 40.0
    max_live: int = 300
    max_retired: int = 5000
    sustain_frames: int = 3
    reseed_after_frames: int = 3
    birth_every_s: float = 1.0
    retired_as_gap: bool = False

    @property
    def miss_log_lr(self) -> float:
        """Log-likelihood ratio against a hypothesis per landmark it predicts well in view
        where no spot is, when nothing is known of that landmark: -ln P(no spot), the
        landmark dark or hidden (`dark_prior`) or lit and missed (`miss_prior`)."""
        p = self.dark_prior + (1.0 - self.dark_prior) * self.miss_prior
        return -math.log(p)


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


def prior_mahalanobis2(
    hyps: FloatArray, prior: tuple[float, float, float], prior_covariance: FloatArray
) -> FloatArray:
    """Squared Mahalanobis distance of each hypothesis (H, 3) from the prior, heading
    wrapped; +inf for all when the covariance is singular."""
    try:
        info = np.linalg.inv(np.asarray(prior_covariance, dtype=np.float64))
    except np.linalg.LinAlgError:
        return np.full(len(hyps), math.inf)
    d = hyps - np.asarray(prior, dtype=np.float64)
    d[:, 2] = wrap_angle(d[:, 2])
    out: FloatArray = np.einsum("hi,ij,hj->h", d, info, d)
    return out


def unique_hypotheses(hyps: FloatArray, rank: FloatArray, config: RelocalizationConfig) -> IntArray:
    """Indices of one hypothesis per pose cell (`distinct_m`, `distinct_rad`), the one of
    highest `rank` in each, best first."""
    order = np.argsort(-rank, kind="stable")
    cell = np.column_stack(
        [
            np.round(hyps[order, 0] / config.distinct_m),
            np.round(hyps[order, 1] / config.distinct_m),
            np.round(wrap_angle(hyps[order, 2]) / config.distinct_rad),
        ]
    )
    _, first = np.unique(cell, axis=0, return_index=True)
    out: IntArray = order[np.sort(first)]
    return out


def seed_hypotheses(
    view: FrameView,
    prior: tuple[float, float, float],
    prior_covariance: FloatArray,
    config: RelocalizationConfig,
) -> tuple[FloatArray, FloatArray]:
    """Hypotheses from the frame's anchor pairs within the prior's gate, one per pose,
    at most `max_hypotheses` (the nearest the prior).

    Returns:
        (poses shape (H, 3), their squared Mahalanobis distances from the prior (H,)).
    """
    hyps = hypotheses_from_anchor_pairs(view.q, view.anchors, view.positions[:, :2], config)
    m2 = prior_mahalanobis2(hyps, prior, prior_covariance)
    gate = m2 <= config.prior_gate_chi2
    hyps, m2 = hyps[gate], m2[gate]
    keep = unique_hypotheses(hyps, -m2, config)[: config.max_hypotheses]
    return hyps[keep], m2[keep]


def distinct_second(
    hyps: FloatArray, score: FloatArray, best: int, config: RelocalizationConfig
) -> float:
    """The best score among the hypotheses distinct from `hyps[best]` (farther than
    `distinct_m` or turned by more than `distinct_rad`); -inf when there is none."""
    bx, by, bt = hyps[best]
    far = (np.hypot(hyps[:, 0] - bx, hyps[:, 1] - by) > config.distinct_m) | (
        np.abs(wrap_angle(hyps[:, 2] - bt)) > config.distinct_rad
    )
    return float(np.max(score[far])) if np.any(far) else -math.inf


def relocalize(
    camera: CameraModel,
    positions: FloatArray,
    spot_pixels: FloatArray,
    prior: tuple[float, float, float],
    prior_covariance: FloatArray,
    config: RelocalizationConfig,
    miss_weights: FloatArray | None = None,
) -> Relocalization:
    """Map-consistent data association over pose hypotheses, one frame (see the module
    docstring).

    Args:
        positions: landmark positions (of the lit ones only, when LEDs are known dark),
            shape (N, 3).
        spot_pixels: the frame's spots, shape (S, 2).
        prior: the pose thought most likely (dead reckoning).
        prior_covariance: its covariance, shape (3, 3) (widen it for a kidnapped robot).
        miss_weights: each landmark's weight when missing, (N,) (default `miss_log_lr`).

    Returns:
        The outcome; `pairs` is empty unless accepted.
    """
    view = frame_view(camera, positions, spot_pixels, config, miss_weights)
    if view is None:
        return _NONE
    hyps, m2 = seed_hypotheses(view, prior, prior_covariance, config)
    if len(hyps) == 0:
        return _NONE
    hyps, score, counts, done = frame_log_lr(
        camera, view, hyps, config, offset=-0.5 * m2, cutoff=config.margin
    )
    best = int(np.argmax(np.where(done, score, -math.inf)))
    second = distinct_second(hyps, score, best, config)
    pose = (float(hyps[best, 0]), float(hyps[best, 1]), float(hyps[best, 2]))
    out = Relocalization(pose, [], float(score[best]), second, len(hyps))
    if counts[best] < inliers_needed(view, config) or score[best] - second < config.margin:
        return out
    pairs = inlier_pairs(view, hyps[best], config)
    return Relocalization(pose, pairs, out.score, second, len(hyps))
