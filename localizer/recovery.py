"""Getting lost and finding the way back: what the localizer keeps between frames to notice
that its pose no longer explains the ceiling, and to find itself again without LEDs.

- Frames whose spots no fused fix explained are counted (`rejections`) with the time of
  the last explained frame: after a stretch long enough for the robot to have been carried
  (a kidnap), the frame's position sigma is widened to that carry; after
  `FusionConfig.lost_after_rejections` (or once the position sigma passes `lost_sigma_m`)
  the localizer is `lost`.
- Where it got lost (`lost_at`) seeds the re-localization hypotheses kept alive over frames
  while lost (`HypothesisSet`), searched within the distance odometry has driven since;
  after long dead reckoning one frame is tried around the filter's pose every
  `RelocalizationConfig.every_s`.
- What tracking learnt of each landmark (lit, dark: `LandmarkLiveness`) weighs a
  landmark's absence against a hypothesis.
- Fixes the odometry disagrees with (`FixRun`): once a run of them forms one track the robot
  could have driven by itself, the odometry is what is wrong (a stall, a spinning wheel, a
  bump) and the filter is re-seeded at the last one.

docs/localizer-recovery.md describes the method. Sans-I/O: time arrives as an argument.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.after_frame import AfterFrame
from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.events import Mode
from localizer.fix_run import FixRun
from localizer.handoff import position_sigma_m
from localizer.hypothesis_set import HypothesisSet
from localizer.landmark_liveness import LandmarkLiveness
from localizer.landmark_map import LandmarkMap
from localizer.landmark_tracker import LandmarkTracker
from localizer.odometry_track import OdometryTrack
from localizer.pose import PoseFix
from localizer.pose_filter import PoseFilter
from localizer.spots import Spots
from localizer.types import FloatArray, IntArray

_NS = 1e-9

# where it got lost: pose, position sigma (m), heading variance, raw odometry pose
LostAt = tuple[float, float, float, float, float, tuple[float, float, float]]


class Recovery:
    """The bookkeeping of getting lost and re-localizing (see the module docstring).

    Attributes:
        rejections: frames in a row whose spots no fused fix explained.
        travel_m: odometry travel since the last fused fix (the slip hypothesis), metres.
        t_explained_ns: the last frame whose spots a fix explained (or none were predicted).
        lost_by_disagreement: lost because the spots disagreed (not the sigma's growth).
        lost_at: where it got lost (`LostAt`).
        hypotheses: the re-localization hypotheses carried over frames while lost.
        liveness: what tracking learnt of each landmark (lit, dark), per map row.
        fix_run: fixes the odometry disagrees with, and the last fused one they must link to.
    """

    def __init__(
        self,
        config: LocalizerConfig,
        n_landmarks: int,
        *,
        max_speed_m_s: float,
        max_turn_rad_s: float,
        spacing_m: float,
    ) -> None:
        self.config = config
        self.rejections = 0
        self.travel_m = 0.0
        self.t_explained_ns = 0
        self.lost_by_disagreement = False
        self.lost_at: LostAt = (0.0, 0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0))
        self.hypotheses = HypothesisSet(config.relocalization)
        self._t_relocalized: int | None = None  # the last one-frame re-localization
        self._max_speed_m_s, self._max_turn_rad_s = max_speed_m_s, max_turn_rad_s
        self.set_map(n_landmarks, spacing_m)

    def set_map(self, n_landmarks: int, spacing_m: float) -> None:
        """A new map (`spacing_m`: its landmarks' spacing): nothing learnt of its landmarks
        yet, no run of fixes."""
        self.fix_run = FixRun(
            self.config.fix_run,
            max_speed_m_s=self._max_speed_m_s,
            max_turn_rad_s=self._max_turn_rad_s,
            spacing_m=spacing_m,
        )
        self.liveness = LandmarkLiveness(n_landmarks, self.config.relocalization)
        self._t_liveness: int | None = None

    def reset(self, t_ns: int) -> None:
        """The filter was reset at `t_ns` (a fix, a prior): everything explained there."""
        self.rejections = 0
        self.travel_m = 0.0
        self.t_explained_ns = t_ns
        self.hypotheses.clear()
        self.fix_run.clear()

    def tracked(self, t_ns: int, used: tuple[int, ...], unexplained: bool) -> None:
        """A tracking step's outcome: a fix fused (`used`), or spots no fix explained."""
        if used:
            self.rejections = 0
            self.travel_m = 0.0
        elif unexplained:
            self.rejections += 1
        if not unexplained:
            self.t_explained_ns = t_ns

    def widen_unexplained(self, filt: PoseFilter, t_ns: int, spacing_m: float) -> None:
        """After frames whose spots no fix explained, the robot may have been moved without
        its odometry knowing (a kidnap): once `carry_speed_m_s` x the time since the last
        explained frame reaches half the landmark spacing (a shorter stretch, a bump or a
        glint, cannot pair a spot with another landmark's prediction and is tracked through
        as before), this frame's spots are matched with the position sigma widened to it
        (the frame's copy of the filter; kept only with a fix). Past `reacquire_sigma_m` a
        match needs the geometric check, which on a regular grid finds the pose one spacing
        away as good as the old one and takes neither."""
        if self.rejections == 0:
            return
        sigma = self.config.fusion.carry_speed_m_s * (t_ns - self.t_explained_ns) * _NS
        if sigma < 0.5 * spacing_m:
            return  # too short a carry to pair a spot with another landmark's prediction
        P = filt.covariance_rows
        var = sigma * sigma - min(P[0][0], P[1][1])
        if var > 0:
            filt.inflate(var, 0.0)

    def lost_sigma(self, filt: PoseFilter) -> float | None:
        """The position sigma (metres) when the localizer is lost now (past `lost_sigma_m`,
        or `lost_after_rejections` frames in a row unexplained); None while it is not."""
        fc = self.config.fusion
        sigma = position_sigma_m(filt.covariance_rows)
        if sigma > fc.lost_sigma_m or self.rejections >= fc.lost_after_rejections:
            return sigma
        return None

    def lose(
        self, filt: PoseFilter, sigma: float, odometry_pose: tuple[float, float, float]
    ) -> None:
        """The localizer got lost with position sigma `sigma`: note why and where, and
        when the spots disagreed, widen the filter's uncertainty so that a map-consistent
        re-acquisition can correct it."""
        fc = self.config.fusion
        self.lost_by_disagreement = sigma <= fc.lost_sigma_m
        if sigma < fc.lost_sigma_m or self.rejections > 0:
            # The observations disagree with the pose (a kidnapped robot, put down
            # anywhere, facing anywhere): widen its uncertainty so that a map-consistent
            # re-acquisition can correct it.
            x, y, th = (float(v) for v in filt.state)
            cov = filt.covariance
            cov[:2, :2] = np.eye(2) * max(fc.lost_sigma_m, sigma) ** 2
            cov[:2, 2] = cov[2, :2] = 0.0
            cov[2, 2] = max(float(cov[2, 2]), fc.lost_sigma_rad**2)
            filt.reset(x, y, th, cov)
        x, y, th = (float(v) for v in filt.state)
        var_th = float(filt.covariance[2, 2])
        sigma0 = max(position_sigma_m(filt.covariance_rows), fc.lost_sigma_m)
        self.lost_at = (x, y, th, sigma0, var_th, odometry_pose)
        self.hypotheses.clear()
        self.fix_run.clear()

    def relocalize(
        self,
        tracker: LandmarkTracker,
        filt: PoseFilter,
        spots: Spots,
        candidates: IntArray | None,
        *,
        mode: Mode,
        t_ns: int,
        odometry: OdometryTrack,
    ) -> PoseFix | None:
        """Re-localization without LEDs: while lost (or identifying from a prior), the
        hypothesis set carried over frames (seeded around where it got lost, within the
        distance odometry has driven since; or around the prior: the filter's pose and
        covariance); after long dead reckoning, one frame around the filter's pose, every
        `every_s`. Returns the fix of the one unambiguous hypothesis, or None."""
        if mode in ("lost", "identifying"):
            odo = odometry.pose
            prior = None  # identifying with a prior: the filter's pose and covariance
            if mode == "lost":
                x, y, th, sigma0, var_th, odo0 = self.lost_at
                sigma = sigma0 + math.hypot(odo[0] - odo0[0], odo[1] - odo0[1])
                prior = ((x, y, th), np.diag([sigma**2, sigma**2, var_th]))
            return tracker.relocalize(
                filt,
                spots,
                candidates,
                prior=prior,
                hypotheses=self.hypotheses,
                t_ns=t_ns,
                odometry_pose=odo,
                miss_weights=self.miss_weights(),
            )
        every = self.config.relocalization.every_s
        if self._t_relocalized is not None and (t_ns - self._t_relocalized) * _NS < every:
            return None
        self._t_relocalized = t_ns
        return tracker.relocalize(filt, spots, candidates, miss_weights=self.miss_weights())

    def reseed(
        self, t_ns: int, fix: PoseFix, tracker: LandmarkTracker, filt: PoseFilter
    ) -> tuple[int, ...]:
        """A good fix the filter rejected: when it completes (or continues) a run of such
        fixes that form one track the robot could have driven by itself (`fix_run`), the
        filter is re-seeded at it (`LandmarkTracker.adopt_rejected`); returns its IDs
        (empty: not taken)."""
        if not self.fix_run.offer(t_ns, fix):
            return ()
        return tracker.adopt_rejected(filt)

    def learn_liveness(
        self,
        t_ns: int,
        camera: CameraModel,
        landmark_map: LandmarkMap,
        expected: tuple[int, ...],
        tracker: LandmarkTracker,
        filt: PoseFilter,
        after: AfterFrame,
    ) -> None:
        """A fused frame (at most every `score_every_s`): which landmarks predicted well in
        view (`expected`) were detected (`LandmarkLiveness.observe_frame`), learnt after
        the frame's pose is out (`after`, with the frame's pose and spots)."""
        every = self.config.relocalization.score_every_s
        fused = tracker.last_fused
        if fused is None:
            return
        if self._t_liveness is not None and (t_ns - self._t_liveness) * _NS < every:
            return
        self._t_liveness = t_ns
        x, y, th = (float(v) for v in filt.state)
        liveness, index, positions = self.liveness, landmark_map.index_of, landmark_map.positions

        def learn() -> None:
            rows, px, _ = fused
            liveness.observe_frame(
                camera,
                (x, y, th),
                positions,
                np.array([index(i) for i in expected], dtype=np.int64),
                np.asarray(rows, dtype=np.int64),
                np.asarray(px, dtype=np.float64).reshape(-1, 2),
            )

        after.defer(learn)

    def miss_weights(self) -> FloatArray:
        """What each landmark's absence weighs against a hypothesis (`LandmarkLiveness`),
        one per map row; fixed while lost (nothing is learnt then)."""
        return self.liveness.miss_log_lr()
