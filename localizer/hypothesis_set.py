"""Recovery from `lost` without LEDs: map-consistent pose hypotheses kept alive over frames.

One frame of a regular grid is ambiguous: a pose one spacing (or a quarter turn at a corner)
away explains every spot as well (`relocalization.relocalize` then says nothing). A robot
keeps driving, though, and the ambiguity resolves once the grid's edge, a gap or any
irregularity of the map comes into view. `HypothesisSet` keeps the hypotheses alive while
the localizer is lost:

- *seeded* from a frame (`relocalization.seed_hypotheses`: anchor pairs matched to landmark
  pairs, within the prior's gate), each scored by that frame plus the prior's log density;
- *carried* by the odometry's relative motion every frame (`compose_odometry`, eqs. 5-6 as
  the raw dead reckoning integrated them);
- *scored* by every frame (at most every `score_every_s`): `hypothesis_scoring.frame_log_lr`,
  every spot for it, every landmark it predicts well inside the image with no spot there
  against it (negative evidence), refit to its inliers (odometry drift never accumulates);
  one frame lowers a hypothesis by at most `frame_clip` against that frame's best. The sum is
  the log-likelihood ratio of the hypothesis over the frames it has lived;
- *pruned* when `prune_below` under the best, merged when two converge on one pose;
- *born*: every `birth_every_s` the current frame seeds again; new poses join `margin` below
  the best (a late-comer must earn its lead);
- *re-seeded* when the best explains too few spots on `reseed_after_frames` scored frames in a
  row (carried off again, or the truth was never among them).

The best is accepted only when it is unambiguous: it explains the frame (`min_inliers`,
`min_inlier_fraction`), the frame itself does not prefer another by `margin`, and it leads
every distinct hypothesis by `margin` on `sustain_frames` scored frames in a row. A map that
is symmetric (a perfect rectangular grid turned by half a turn about its centre) can never
be resolved from the spots: then the set stays ambiguous and the localizer stays `lost`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from localizer.camera import CameraModel
from localizer.geometry import wrap_angle
from localizer.hypothesis_scoring import (
    FrameView,
    frame_log_lr,
    frame_view,
    inlier_pairs,
    inliers_needed,
)
from localizer.relocalization import (
    Relocalization,
    RelocalizationConfig,
    distinct_second,
    seed_hypotheses,
    unique_hypotheses,
)
from localizer.types import FloatArray, Pose

_NS = 1e-9


Seeder = Callable[
    [FrameView, Pose, FloatArray, RelocalizationConfig], tuple[FloatArray, FloatArray]
]
"""Hypotheses of a frame within a prior's gate: (poses (H, 3), squared Mahalanobis
distances from the prior (H,)); `relocalization.seed_hypotheses` by default."""


class Seed(NamedTuple):
    """What seeding needs of one frame: the camera, the frame, the prior."""

    camera: CameraModel
    view: FrameView
    prior: Pose
    prior_covariance: FloatArray


def same_pose_min(
    hyps: FloatArray, others: FloatArray, values: FloatArray, config: RelocalizationConfig
) -> FloatArray:
    """For each hypothesis (H, 3), the smallest of `values` (K,) over the `others` (K, 3)
    that are the same pose (within `distinct_m` and `distinct_rad`; the nearest 16 looked
    at); +inf where none is."""
    if not len(hyps) or not len(others):
        return np.full(len(hyps), math.inf)
    k = min(16, len(others))
    dist, idx = cKDTree(others[:, :2]).query(
        hyps[:, :2], k=k, distance_upper_bound=config.distinct_m
    )
    dist, idx = dist.reshape(len(hyps), k), idx.reshape(len(hyps), k)
    near = np.isfinite(dist)
    safe = np.where(near, idx, 0)
    near &= np.abs(wrap_angle(others[safe, 2] - hyps[:, 2, None])) <= config.distinct_rad
    out: FloatArray = np.min(np.where(near, values[safe], math.inf), axis=1)
    return out


def compose_odometry(hyps: FloatArray, odo_then: Pose, odo_now: Pose) -> FloatArray:
    """Each hypothesis moved by the odometry's relative motion from `odo_then` to `odo_now`
    (raw odometry poses in their own frame): the body-frame displacement and turn applied
    in each hypothesis's own frame.

    Args:
        hyps: poses (x, y, theta), shape (H, 3).

    Returns:
        The moved poses, shape (H, 3), headings in (-pi, pi].
    """
    c0, s0 = math.cos(odo_then[2]), math.sin(odo_then[2])
    dx, dy = odo_now[0] - odo_then[0], odo_now[1] - odo_then[1]
    fx, fy = c0 * dx + s0 * dy, -s0 * dx + c0 * dy  # the displacement in the body frame
    dth = float(wrap_angle(odo_now[2] - odo_then[2]))
    c, s = np.cos(hyps[:, 2]), np.sin(hyps[:, 2])
    out = np.empty_like(hyps)
    out[:, 0] = hyps[:, 0] + c * fx - s * fy
    out[:, 1] = hyps[:, 1] + s * fx + c * fy
    out[:, 2] = wrap_angle(hyps[:, 2] + dth)
    return out


class HypothesisSet:
    """The live pose hypotheses of a lost robot (see the module docstring).

    Args:
        config: the tuning (`RelocalizationConfig`, its "over frames" part).
        seeder: how a frame seeds hypotheses (default `relocalization.seed_hypotheses`,
            anchor pairs; `constellation` seeds by triangles for passive lights).

    Attributes:
        poses: the live hypotheses (x, y, theta), shape (H, 3).
        log_lr: each one's log-likelihood ratio against the best of each frame, summed over
            the frames it lived (0 for one that was the best on every frame), shape (H,).
        retired: poses no longer scored (refuted: `prune_below` under the best, or a seed
            that did not explain its frame; or beyond `max_live`), still carried by the
            odometry, shape (R, 3); `retired_lr` their log-likelihood ratio then, (R,). The
            evidence against them is not forgotten: seeded again, they start from it.
        sustained: scored frames in a row on which the best was unambiguous.
    """

    def __init__(self, config: RelocalizationConfig, seeder: Seeder = seed_hypotheses) -> None:
        self.config = config
        self.seeder = seeder
        self.clear()

    def __len__(self) -> int:
        return len(self.poses)

    def clear(self) -> None:
        """Forget every hypothesis (the next `update` seeds afresh)."""
        self.poses: FloatArray = np.zeros((0, 3))
        self.log_lr: FloatArray = np.zeros(0)
        self.retired: FloatArray = np.zeros((0, 3))
        self.retired_lr: FloatArray = np.zeros(0)
        self._counted = np.zeros((0, 0), dtype=bool)  # (H, N): misses counted already
        self.sustained = 0
        self._unhealthy = 0
        self._odometry: Pose | None = None
        self._t_scored: int | None = None
        self._t_born: int | None = None

    def update(
        self,
        t_ns: int,
        odometry_pose: Pose,
        camera: CameraModel,
        positions: FloatArray,
        spot_pixels: FloatArray,
        prior: Pose,
        prior_covariance: FloatArray,
        miss_weights: FloatArray | None = None,
    ) -> Relocalization:
        """One frame: carry the hypotheses to it, score them (or seed), decide.

        Args:
            t_ns: the frame's time.
            odometry_pose: the raw odometry pose at the frame (any fixed frame).
            positions: the landmarks that may be lit, shape (N, 3).
            spot_pixels: the frame's spots, shape (S, 2).
            prior, prior_covariance: where the robot may be, for seeding (3, 3).
            miss_weights: each landmark's weight when missing (N,)
                (`landmark_liveness.LandmarkLiveness.miss_log_lr`); default
                `miss_log_lr` each. Keep it fixed while lost: a miss counts once.

        Returns:
            The best hypothesis; `pairs` (its inliers on this frame) only when accepted.
        """
        c = self.config
        if self._odometry is not None:
            self.poses = compose_odometry(self.poses, self._odometry, odometry_pose)
            self.retired = compose_odometry(self.retired, self._odometry, odometry_pose)
        self._odometry = odometry_pose
        if self._t_scored is not None and (t_ns - self._t_scored) * _NS < c.score_every_s:
            return self._outcome(None, [])
        self._t_scored = t_ns
        view = frame_view(camera, positions, spot_pixels, c, miss_weights)
        if view is None:
            return self._fail()
        seed = Seed(camera, view, prior, prior_covariance)
        frame, counts = np.zeros(0), np.zeros(0)
        if self._counted.shape != (len(self.poses), len(positions)):
            self._counted = np.zeros((len(self.poses), len(positions)), dtype=bool)
        if len(self.poses):
            self.poses, frame, counts, _ = frame_log_lr(
                camera, view, self.poses, c, refits=0, counted=self._counted
            )
            self._add_frame(frame)
        if (
            not len(self.poses)
            or self._t_born is None
            or ((t_ns - self._t_born) * _NS >= c.birth_every_s)
        ):
            frame, counts = self._births(seed, frame, counts)
            self._t_born = t_ns
        if not len(self.poses):
            return self._fail()
        best = int(np.argmax(self.log_lr))
        if counts[best] < inliers_needed(view, c):
            out = self._fail()
        else:
            self._unhealthy = 0
            out = self._decide(best, frame, counts, seed, t_ns)
        self._prune()
        return out

    # -- internals ---------------------------------------------------------------------------
    def _add_frame(self, frame: FloatArray) -> None:
        """Each hypothesis's log-likelihood ratio on this frame against the frame's best,
        no lower than `-frame_clip`, added to its sum."""
        clip = self.config.frame_clip
        self.log_lr = self.log_lr + np.clip(frame - float(np.max(frame)), -clip, 0.0)

    def _decide(
        self, best: int, frame: FloatArray, counts: FloatArray, seed: Seed, t_ns: int
    ) -> Relocalization:
        """Accept the best when it leads every distinct one (and this frame does not prefer
        another) on `sustain_frames` scored frames in a row, and no pose explaining this
        frame is missing from the set (a late-comer is born as good as the best: the lead
        must be earned against it)."""
        c = self.config
        second = self._second(best)
        lead = self.log_lr[best] - second >= c.margin
        agrees = frame[best] >= float(np.max(frame)) - c.margin
        self.sustained = self.sustained + 1 if lead and agrees else 0
        if self.sustained < c.sustain_frames:
            return self._outcome(best, [], second)
        if self._t_born != t_ns:
            frame, counts = self._births(seed, frame, counts)
            self._t_born = t_ns
            best = int(np.argmax(self.log_lr))
            second = self._second(best)
            if self.log_lr[best] - second < c.margin or frame[best] < np.max(frame) - c.margin:
                self.sustained = 0  # a late-comer as good: the lead must be earned again
                return self._outcome(best, [], second)
        return self._outcome(best, inlier_pairs(seed.view, self.poses[best], c), second)

    def _second(self, best: int) -> float:
        """The best score of any pose distinct from the best, the retired ones included
        (one dropped beyond `max_live` keeps its score: the lead must be earned on it too)."""
        c = self.config
        poses = np.vstack([self.poses, self.retired])
        log_lr = np.concatenate([self.log_lr, self._retired_now()])
        return distinct_second(poses, log_lr, best, c)

    def _births(
        self, seed: Seed, frame: FloatArray, counts: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Seed from this frame (the first time with the prior's log density). A pose not
        alive starts from its retired record, or, never tracked, as if it had tied with the
        best on every earlier frame; it joins the set when it explains this frame, else it
        is retired (refuted)."""
        c = self.config
        first = not len(self.poses)
        hyps, m2 = self.seeder(seed.view, seed.prior, seed.prior_covariance, c)
        if len(hyps) and not first:
            new = ~np.isfinite(same_pose_min(hyps, self.poses, np.zeros(len(self.poses)), c))
            hyps, m2 = hyps[new], m2[new]
        if not len(hyps):
            return frame, counts
        clip = c.frame_clip
        counted = np.zeros((len(hyps), len(seed.view.positions)), dtype=bool)
        hyps, score, n_in, done = frame_log_lr(
            seed.camera,
            seed.view,
            hyps,
            c,
            offset=-0.5 * m2 if first else None,
            cutoff=clip,
            counted=counted,
        )
        f_live = float(np.max(frame)) if len(frame) else -math.inf
        f_all = max(f_live, float(np.max(score[done])) if np.any(done) else -math.inf)
        if first:
            L_base = np.zeros(len(hyps))
        else:
            # before this frame: the best's sum (this frame's increment taken out again)
            L_before = float(np.max(self.log_lr - np.clip(frame - f_live, -clip, 0.0)))
            retired = self._retired_now()
            L_base = np.minimum(L_before, same_pose_min(hyps, self.retired, retired, c))
            # this frame against the best of all, the newborns included
            self.log_lr = (
                self.log_lr
                + np.clip(frame - f_all, -clip, 0.0)
                - np.clip(frame - f_live, -clip, 0.0)
            )
        joins = done & (n_in >= inliers_needed(seed.view, c)) & (score >= f_all - clip)
        L = L_base + np.clip(score - f_all, -clip, 0.0)
        self.poses = np.vstack([self.poses, hyps[joins]])
        self.log_lr = np.concatenate([self.log_lr, L[joins]])
        self._counted = np.vstack([self._counted, counted[joins]])
        if np.any(joins) and len(self.retired):  # alive again: no longer retired
            back = np.isfinite(same_pose_min(self.retired, hyps[joins], L[joins], c))
            self.retired, self.retired_lr = self.retired[~back], self.retired_lr[~back]
        self._retire(hyps[~joins], L_base[~joins] - clip)
        return np.concatenate([frame, score[joins]]), np.concatenate([counts, n_in[joins]])

    def _retire(self, poses: FloatArray, log_lr: FloatArray) -> None:
        """Retire poses: one record per pose, the strongest evidence against it."""
        if not len(poses):
            return
        if self.config.retired_as_gap and len(self.log_lr):
            log_lr = log_lr - float(np.max(self.log_lr))  # kept as the gap to the best
        R = np.vstack([poses, self.retired])
        L = np.concatenate([log_lr, self.retired_lr])
        keep = unique_hypotheses(R, -L, self.config)[: self.config.max_retired]
        self.retired, self.retired_lr = R[keep], L[keep]

    def _retired_now(self) -> FloatArray:
        """The retired poses' log-likelihood ratios on the live ones' scale: as they were
        when retired, or (`retired_as_gap`) the best's now less their gap to the best then
        (the best's own sum sinks on frames a newborn leads; a frozen sum would then look
        better than the pose ever was)."""
        if not self.config.retired_as_gap or not len(self.log_lr):
            return self.retired_lr
        out: FloatArray = self.retired_lr + float(np.max(self.log_lr))
        return out

    def _prune(self) -> None:
        c = self.config
        if not len(self.poses):
            return
        keep = self.log_lr >= float(np.max(self.log_lr)) - c.prune_below
        self._retire(self.poses[~keep], self.log_lr[~keep])
        self.poses, self.log_lr = self.poses[keep], self.log_lr[keep]
        self._counted = self._counted[keep]
        order = unique_hypotheses(self.poses, self.log_lr, c)
        self._retire(self.poses[order[c.max_live :]], self.log_lr[order[c.max_live :]])
        order = order[: c.max_live]
        self.poses, self.log_lr, self._counted = (
            self.poses[order],
            self.log_lr[order],
            self._counted[order],
        )

    def _fail(self) -> Relocalization:
        """The best explains too little of this frame: after `reseed_after_frames` such
        frames in a row the set has died."""
        self.sustained = 0
        self._unhealthy += 1
        if self._unhealthy >= self.config.reseed_after_frames:
            odometry = self._odometry
            self.clear()
            self._odometry = odometry
        return self._outcome(None, [])

    def _outcome(
        self, best: int | None, pairs: list[tuple[int, int]], second: float = -math.inf
    ) -> Relocalization:
        if best is None or not len(self.poses):
            return Relocalization(None, [], -math.inf, -math.inf, len(self.poses))
        x, y, th = (float(v) for v in self.poses[best])
        return Relocalization((x, y, th), pairs, float(self.log_lr[best]), second, len(self.poses))
