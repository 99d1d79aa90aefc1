"""Identification by geometry: a frame's spots matched to the map as a constellation.

Landmarks that cannot blink (a building's own ceiling lights, LEDs whose radio is out) can
only be told apart by where they are. Seen from an upward camera, the lights of one frame
are a rigidly moved copy of a patch of the map, so:

1. every spot's ray meets the ceiling (the map's median height) in the body frame:
   `q_s`, shape (S, 2) (`hypothesis_scoring.frame_view`);
2. *invariants*: a triangle of spots has the same three side lengths as the triangle of
   landmarks it shows (a rigid motion of the plane keeps distances; no mirror image: the
   signed area keeps its sign). Spot triangles come from the spots nearest the image centre
   (least distorted), sides at least `min_side_m`; the map's triangles with every side
   within the view are indexed by their sorted sides (`triangles.py`);
3. *hypotheses*: each spot triangle against each map triangle whose sorted sides agree
   within the tolerance, in each of the three cyclic vertex orders that agree side by side,
   gives a planar pose by 2D rigid registration (Kabsch) of the three points
   (`triangles.triangle_hypotheses`); with a prior, those outside its gate are dropped;
4. *verification by every spot*: each hypothesis carries every spot into the world, counts
   the spots a landmark explains, refits to them, and counts against it every landmark it
   predicts well inside the image where no spot is (`hypothesis_scoring.frame_log_lr`);
5. *decision* (`match_constellation`): the best is accepted only when it explains the frame
   and leads every distinct pose by `margin` (log-likelihood). A regular grid leaves poses
   one spacing (or a quarter turn) apart scoring alike: that is reported as `ambiguous`,
   with the tied poses, not guessed; a prior pose, the robot's motion over frames
   (`passive_identification`) or an irregularity of the map coming into view decides.

Tolerances come from the landmarks' own uncertainty (`landmark_sigma_m`: a panel's centroid
scatters by centimetres where an LED's does not) and the ceiling points' (`ceiling_sigma_m`:
the calibration, the ceiling's height, a tilt), in quadrature.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from localizer.camera import CameraModel
from localizer.hypothesis_scoring import (
    FrameView,
    frame_log_lr,
    frame_view,
    inlier_pairs,
    inliers_needed,
)
from localizer.relocalization import (
    RelocalizationConfig,
    distinct_second,
    prior_mahalanobis2,
    unique_hypotheses,
)
from localizer.triangles import MapTriangles, spot_triangles, triangle_hypotheses
from localizer.types import FloatArray

MatchStatus = Literal["unique", "ambiguous", "no_match", "too_few_spots"]


@dataclass(frozen=True)
class ConstellationConfig:
    """Tuning of the constellation match.

    Attributes:
        anchor_spots: spot triangles are formed from this many spots nearest the centre.
        max_spot_triangles: at most this many spot triangles are tried (the largest first:
            a long side turns a distance error into the least heading error).
        min_side_m: a triangle's shortest side must be at least this, metres (a sliver
            gives no heading).
        ceiling_sigma_m: 1-sigma error of a spot's ceiling point (calibration, ceiling
            height, tilt), metres.
        tolerance_sigmas: sides and inliers agree within this many sigmas.
        tolerance_frac: plus this fraction of the length (a wrong ceiling height scales).
        max_map_triangles: at most this many map triangles are indexed (the nearest first:
            a dense LED grid has millions within a wide view); beyond, the view's triangles
            are cut to the shortest sides.
        margin: the best must lead every distinct pose by this (log-likelihood; 9 is about
            8000:1).
        max_hypotheses: at most this many hypotheses are verified (nearest a prior, else in
            the order found).
        birth_every_s: over frames, new hypotheses are seeded at most this often, seconds
            (the first frame seeds every pose the map allows; later ones add what it missed).
        reseed_after_frames: over frames, the set is seeded afresh after this many scored
            frames in a row that its best does not explain.
    """

    anchor_spots: int = 7
    max_spot_triangles: int = 12
    min_side_m: float = 0.3
    ceiling_sigma_m: float = 0.03
    tolerance_sigmas: float = 3.0
    tolerance_frac: float = 0.02
    max_map_triangles: int = 300_000
    margin: float = 9.0
    max_hypotheses: int = 4000
    birth_every_s: float = 4.0
    reseed_after_frames: int = 10

    def __post_init__(self) -> None:
        if self.anchor_spots < 3 or self.max_spot_triangles < 1 or self.max_hypotheses < 1:
            raise ValueError(
                "ConstellationConfig: anchor_spots >= 3, max_spot_triangles and max_hypotheses >= 1"
            )
        for name in ("min_side_m", "ceiling_sigma_m", "tolerance_sigmas", "margin"):
            if not getattr(self, name) > 0:
                raise ValueError(f"ConstellationConfig: {name} must be > 0")

    def tolerance_m(self, landmark_sigma_m: float) -> float:
        """How far a ceiling point may lie from its landmark: `tolerance_sigmas` x the
        landmark's and the ceiling point's sigmas in quadrature, metres."""
        return self.tolerance_sigmas * math.hypot(landmark_sigma_m, self.ceiling_sigma_m)


class ConstellationMatch(NamedTuple):
    """The outcome of `match_constellation`.

    Attributes:
        status: "unique" (accepted), "ambiguous" (several distinct poses explain the frame
            alike), "no_match" (none explains it), "too_few_spots".
        reason: one sentence for a person: what was seen and why it was (not) accepted.
        pose: the best pose (x, y, theta), None without any.
        pairs: its (map row, spot index) inliers when accepted, else empty.
        candidates: the distinct poses within `margin` of the best, best first, (K, 3)
            (one row when unique).
        score, second: the best's log-likelihood and the best distinct other's (-inf).
        hypotheses: how many were verified.
    """

    status: MatchStatus
    reason: str
    pose: tuple[float, float, float] | None
    pairs: list[tuple[int, int]]
    candidates: FloatArray
    score: float
    second: float
    hypotheses: int


def scoring_config(
    base: RelocalizationConfig, config: ConstellationConfig, landmark_sigma_m: float
) -> RelocalizationConfig:
    """The hypothesis scoring's tolerances widened to the landmarks' own uncertainty (a
    panel's centroid is not an LED's point), never narrowed; three inliers explain a frame
    (a view of lights metres apart holds few: a set that needed four died on every frame
    that showed three, and its evidence with it); new hypotheses born over frames at most
    every `birth_every_s` (`hypothesis_set`: a newborn ties with the best, and on a nearly
    regular ceiling one was born every second, so the lead the map's few irregularities
    give never built up), and the set re-seeded only after `reseed_after_frames` frames it
    does not explain (under a missing light, where the evidence is, fewer lights are in
    view); retired poses keep their gap to the best (their frozen sums outscored a best whose
    own sum had sunk on the frames newborns led: a lead of 25 read as 8.9)."""
    tol = config.tolerance_m(landmark_sigma_m)
    return dataclasses.replace(
        base,
        min_inliers=min(base.min_inliers, 3),
        birth_every_s=max(base.birth_every_s, config.birth_every_s),
        reseed_after_frames=max(base.reseed_after_frames, config.reseed_after_frames),
        retired_as_gap=True,
        anchor_spots=max(base.anchor_spots, config.anchor_spots),
        inlier_tolerance_m=max(base.inlier_tolerance_m, tol),
        distance_tolerance_m=max(base.distance_tolerance_m, tol),
        distinct_m=max(base.distinct_m, tol),
        margin=config.margin,
    )


def constellation_hypotheses(
    view: FrameView,
    index: MapTriangles,
    config: ConstellationConfig,
    landmark_sigma_m: float,
    prior: tuple[tuple[float, float, float], FloatArray] | None = None,
    prior_gate_chi2: float = 25.0,
) -> tuple[FloatArray, FloatArray]:
    """The frame's hypotheses (steps 2-3), one per pose cell, within a prior's gate.

    Returns:
        (poses shape (H, 3), squared Mahalanobis distances from the prior (H,), zeros
        without a prior), at most `max_hypotheses` (the nearest the prior first).
    """
    tris = spot_triangles(view.q, view.anchors, config.min_side_m, config.max_spot_triangles)
    hyps = triangle_hypotheses(
        view.q,
        tris,
        view.positions[:, :2],
        index,
        config.tolerance_m(landmark_sigma_m),
        config.tolerance_frac,
    )
    if prior is None:
        m2 = np.zeros(len(hyps))
    else:
        m2 = prior_mahalanobis2(hyps, prior[0], prior[1])
        hyps, m2 = hyps[m2 <= prior_gate_chi2], m2[m2 <= prior_gate_chi2]
    cells = RelocalizationConfig(distinct_m=0.5 * config.tolerance_m(landmark_sigma_m) + 0.02)
    keep = unique_hypotheses(hyps, -m2, cells)[: config.max_hypotheses]
    return hyps[keep], m2[keep]


def _pose_text(p: FloatArray) -> str:
    return f"({p[0]:.2f}, {p[1]:.2f}, {math.degrees(p[2]):.0f} deg)"


def match_constellation(
    camera: CameraModel,
    positions: FloatArray,
    spot_pixels: FloatArray,
    index: MapTriangles,
    config: ConstellationConfig,
    scoring: RelocalizationConfig,
    *,
    landmark_sigma_m: float,
    prior: tuple[tuple[float, float, float], FloatArray] | None = None,
    miss_weights: FloatArray | None = None,
) -> ConstellationMatch:
    """Identify one frame's spots by geometry alone (steps 1-5 of the module docstring).

    Args:
        positions: the landmarks, shape (N, 3) (rows of `index`).
        spot_pixels: the frame's spots, shape (S, 2).
        index: `map_triangles` of `positions[:, :2]`, sides up to the view's width.
        scoring: the hypothesis scoring's tuning (`scoring_config`).
        landmark_sigma_m: the landmarks' typical 1-sigma position error, metres.
        prior: (pose, covariance (3, 3)) where the robot is believed to be; None: anywhere
            (a cold start).
        miss_weights: each landmark's weight when missing, (N,).

    Returns:
        The decision, with a reason a person can act on.
    """
    none = np.zeros((0, 3))
    view = frame_view(camera, positions, spot_pixels, scoring, miss_weights)
    if view is None or len(view.anchors) < 3:
        n = len(spot_pixels)
        return ConstellationMatch(
            "too_few_spots",
            f"{n} spot(s) on the ceiling: a constellation needs 3 or more",
            None,
            [],
            none,
            -math.inf,
            -math.inf,
            0,
        )
    hyps, m2 = constellation_hypotheses(
        view, index, config, landmark_sigma_m, prior, scoring.prior_gate_chi2
    )
    if not len(hyps):
        where = "near the prior pose" if prior is not None else "anywhere in the map"
        return ConstellationMatch(
            "no_match",
            f"no triangle of the {len(view.anchors)} central spots matches one of the map's "
            f"{len(index.vertices)} {where} (tolerance "
            f"{config.tolerance_m(landmark_sigma_m) * 100:.0f} cm)",
            None,
            [],
            none,
            -math.inf,
            -math.inf,
            0,
        )
    offset = None if prior is None else -0.5 * m2
    hyps, score, counts, done = frame_log_lr(
        camera, view, hyps, scoring, offset=offset, cutoff=config.margin
    )
    score = np.where(done, score, -math.inf)
    best = int(np.argmax(score))
    second = distinct_second(hyps, score, best, scoring)
    pose = (float(hyps[best, 0]), float(hyps[best, 1]), float(hyps[best, 2]))
    need = inliers_needed(view, scoring)
    if counts[best] < need:
        return ConstellationMatch(
            "no_match",
            f"the best pose {_pose_text(hyps[best])} explains {int(counts[best])} of "
            f"{len(view.sub)} spots (needs {math.ceil(need)})",
            pose,
            [],
            hyps[best : best + 1],
            float(score[best]),
            second,
            len(hyps),
        )
    tied = score >= score[best] - config.margin
    cand = hyps[tied][unique_hypotheses(hyps[tied], score[tied], scoring)]  # best first
    if score[best] - second < config.margin:
        far = np.hypot(cand[1:, 0] - cand[0, 0], cand[1:, 1] - cand[0, 1])
        return ConstellationMatch(
            "ambiguous",
            f"{len(cand)} distinct poses explain the {len(view.sub)} spots alike "
            f"(best {_pose_text(cand[0])}, next {_pose_text(cand[1])}, "
            f"{float(far[0]) if len(far) else 0.0:.2f} m apart): a regular layout; "
            "give a start pose or drive until the map's edge or an irregularity is in view",
            pose,
            [],
            cand,
            float(score[best]),
            second,
            len(hyps),
        )
    pairs = inlier_pairs(view, hyps[best], scoring)
    return ConstellationMatch(
        "unique",
        f"{len(pairs)} of {len(view.sub)} spots identified; the next distinct pose scores "
        f"{score[best] - second:.0f} lower"
        if math.isfinite(second)
        else f"{len(pairs)} of {len(view.sub)} spots identified; no other pose explains them",
        pose,
        pairs,
        hyps[best : best + 1],
        float(score[best]),
        second,
        len(hyps),
    )


__all__ = [
    "ConstellationConfig",
    "ConstellationMatch",
    "MatchStatus",
    "constellation_hypotheses",
    "match_constellation",
    "scoring_config",
]
