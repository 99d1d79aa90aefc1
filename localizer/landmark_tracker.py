"""One tracking step with a known pose (Sec. IV-A): predict, search, assign, then fuse.

Eq. (3) predicts the lit landmarks' pixels from the filter's pose; spots are searched in
windows sized from speed, frame interval, scale, radius and uncertainty (Sec. IV-A.1) and
assigned by the bottleneck rule; after long dead reckoning (or when asked) only a hypothesis
that agrees with the map's geometry is taken (eq. 4 with a geometric check). The matched
pairs are solved, checked and fused by `FixFusion` (`fix_fusion`), which `LandmarkTracker`
builds on; re-localization without LEDs (`relocalize`) ends in the same solve.

This is the localizer's hot path while tracking: small Python lists instead of numpy arrays
(for three landmarks numpy's per-call cost is most of the work), the windows searched
without a full-frame pass.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.events import FrameObserved, SpotsObserved
from localizer.fix_fusion import FixFusion
from localizer.handoff import (
    Prediction,
    consistent_hypotheses,
    hypothesis_pose,
    pose_mahalanobis2,
    position_sigma_m,
    predict_landmarks,
    visible_radius_m,
)
from localizer.hypothesis_set import HypothesisSet
from localizer.landmark_map import LandmarkMap
from localizer.pose import PoseFix
from localizer.pose_filter import PoseFilter
from localizer.relocalization import relocalize
from localizer.robot import RobotGeometry
from localizer.spot_windows import spot_rows_in_windows
from localizer.spots import Spots, detect_spots, estimate_background
from localizer.tracking import (
    bottleneck_assignment,
    default_angular_speed,
    motion_bound_terms,
    scale_px_per_m,
    unambiguous_pairs,
)
from localizer.types import FloatArray, IntArray

Frame = FrameObserved | SpotsObserved


class TrackResult(NamedTuple):
    """What a tracking step found.

    Attributes:
        used: IDs of the landmarks whose fix was fused (empty: none).
        unexplained: spots were seen while 2+ landmarks were predicted, and no fix was
            fused (the localizer counts these toward getting lost).
        expected: IDs of the lit landmarks predicted inside the image, sorted.
        rejected: a fix consistent in itself (its chi-square passed) that failed the
            innovation gate against the filter, when none was fused (`fix_run`).
    """

    used: tuple[int, ...] = ()
    unexplained: bool = False
    expected: tuple[int, ...] = ()
    rejected: PoseFix | None = None


_NOTHING = TrackResult()


def landmark_spacing_m(positions: FloatArray) -> float:
    """The median horizontal distance from a landmark to its nearest neighbour, metres (inf
    with fewer than two): a displacement under half of it cannot pair a spot with another
    landmark's prediction."""
    if len(positions) < 2:
        return math.inf
    d, _ = cKDTree(positions[:, :2]).query(positions[:, :2], k=2)
    return float(np.median(d[:, 1]))


class LandmarkTracker(FixFusion):
    """Tracking for one camera, robot and map (see the module docstring); the fixes'
    solving and fusing, and the state it keeps (`last_fused`, `floor`, ...), are `FixFusion`'s.

    Args:
        camera, robot, config: as the `Localizer`'s.
        landmark_map: the map; `set_map` replaces it.

    Attributes:
        scale_px_per_m: image scale of the map's ceiling (focal length over its median
            height above the camera).
        max_angular_speed_rad_s: the robot's fastest turn.
        background: the last full frame's background (level, noise), counts; None before.
        spacing_m: the landmarks' typical spacing (`landmark_spacing_m`).
    """

    def __init__(
        self,
        camera: CameraModel,
        robot: RobotGeometry,
        config: LocalizerConfig,
        landmark_map: LandmarkMap,
    ) -> None:
        super().__init__(camera, config)
        self.robot = robot
        self.max_angular_speed_rad_s = config.tracking.max_angular_speed_rad_s or (
            default_angular_speed(robot.max_speed, robot.wheel_base)
        )
        self.background: tuple[float, float] | None = None
        self._unpredicted: tuple[float, float] | None = None  # this step's (`step`)
        self.set_map(landmark_map)

    def set_map(self, landmark_map: LandmarkMap) -> None:
        """Track the landmarks of a new map."""
        heights = landmark_map.positions[:, 2] - self.camera.T_body_camera[2, 3]
        ceiling_m = float(np.median(heights)) if len(heights) else 2.2
        self._use_map(landmark_map, scale_px_per_m(max(self.camera.fu, self.camera.fv), ceiling_m))
        self._reach = visible_radius_m(self.camera, float(np.max(heights, initial=ceiling_m)))
        self.spacing_m = landmark_spacing_m(landmark_map.positions)

    def full_spots(self, e: Frame) -> Spots:
        """The spots of the whole frame (remembering its background for the windows)."""
        if isinstance(e, SpotsObserved):
            return Spots(np.asarray(e.pixels, float).reshape(-1, 2), e.intensities, e.areas)
        self.background = estimate_background(e.image, self.config.detection)
        return detect_spots(e.image, self.config.detection, background=self.background)

    def step(
        self,
        filt: PoseFilter,
        e: Frame,
        *,
        dt_frame_s: float,
        fresh_odometry: bool,
        candidates: IntArray | None,
        spots: Spots | None = None,
        reacquire: bool = False,
        since_sample_s: float = 0.0,
        travel_since_fix_m: float = 0.0,
        unpredicted_bounds: tuple[float, float] | None = None,
    ) -> TrackResult:
        """Find the lit landmarks near their predictions, solve and fuse.

        The prediction extrapolates the last odometry sample's speeds to the frame's time;
        the wheels may have changed speed since (a turn in place starting right after
        driving), or slipped since the last fix. When no fix fits that prediction, a second
        hypothesis is tried: the pose uncertainty widened by an error of each wheel's travel
        of `speed_change_sigma` x the maximum speed over `since_sample_s` and `slip_sigma`
        x `travel_since_fix_m` (the two independent; windows and gates widen with it, most
        at the image edge where a rotation moves spots most).

        Args:
            filt: the pose filter, at the frame's time; a fix is fused into it.
            e: the frame (or its spots).
            dt_frame_s: time since the previous frame, seconds.
            fresh_odometry: odometry arrived recently, so only a fraction of the motion
                since the last frame is unpredicted (`TrackingConfig.odometry_speed_fraction`).
            candidates: map rows of the landmarks surely lit; None: all.
            spots: the frame's spots when already detected (full frame).
            reacquire: require a map-consistent hypothesis (also forced by a large
                position uncertainty).
            since_sample_s: time from the last odometry sample to the frame, seconds.
            travel_since_fix_m: the robot's travel (the mean of its wheels') by odometry
                since the last fused fix, metres.
            unpredicted_bounds: without odometry, the speed and turn rate the motion
                model's prediction may miss (m/s, rad/s; `ConstantVelocity`): the windows'
                motion term over the whole frame interval, instead of the robot's maximum
                speed and turn rate.
        """
        self._unpredicted = unpredicted_bounds
        result = self._attempt(filt, e, dt_frame_s, fresh_odometry, candidates, spots, reacquire)
        tc = self.config.tracking
        sv = math.hypot(
            tc.speed_change_sigma * self.robot.max_speed * max(since_sample_s, 0.0),
            tc.slip_sigma * max(travel_since_fix_m, 0.0),
        )
        if self._unpredicted is not None:
            # Without odometry the second hypothesis is the paper's: any motion within the
            # robot's top speed and turn rate over the frame interval (windows and gates of
            # Sec. IV-A.1, the maximum reach `sigma_gate` sigmas out).
            self._unpredicted = None
            reach_m = self.robot.max_speed * dt_frame_s / tc.sigma_gate
            reach_rad = self.max_angular_speed_rad_s * dt_frame_s / tc.sigma_gate
            var_xy, var_th = reach_m * reach_m, reach_rad * reach_rad
        else:
            var_xy, var_th = 0.5 * sv * sv, 2.0 * (sv / self.robot.wheel_base) ** 2
        if result.used or not result.expected or reacquire or not (var_xy > 0 or var_th > 0):
            return result
        filt.inflate(var_xy, var_th)
        retry = self._attempt(filt, e, dt_frame_s, fresh_odometry, candidates, spots, reacquire)
        if not retry.used:
            return result._replace(rejected=retry.rejected)  # (the one `last_rejected` holds)
        filt.snap_output()  # the correction is motion, not noise: no output lag
        return retry

    def _attempt(
        self,
        filt: PoseFilter,
        e: Frame,
        dt_frame_s: float,
        fresh_odometry: bool,
        candidates: IntArray | None,
        spots: Spots | None,
        reacquire: bool,
    ) -> TrackResult:
        """One prediction, search, assignment and fusion (see `step`)."""
        pose, cov = filt.pose, filt.covariance_rows
        sigma_xy = position_sigma_m(cov)
        pred = predict_landmarks(
            self.camera,
            pose,
            cov,
            self.map.positions,
            candidates=candidates,
            scale_px_per_m=self.scale_px_per_m,
            reach_m=self._reach + 3 * sigma_xy,
        )
        if len(pred) == 0:
            return _NOTHING
        expected = tuple(sorted([self._ids[r] for r in pred.row_list]))
        tc = self.config.tracking
        dt_free = dt_frame_s * (tc.odometry_speed_fraction if fresh_odometry else 1.0)
        px = pred.pixel_list
        cu, cv = self.camera.cu, self.camera.cv
        noise = self.noise.sigma_px
        speed, omega = self._unpredicted or (self.robot.max_speed, self.max_angular_speed_rad_s)
        shift, turn = motion_bound_terms(  # `motion_bound_px`, its terms once per frame
            speed, omega, dt_free, self.scale_px_per_m
        )
        gates = [  # window half sizes and assignment gates, pixels
            tc.min_half_size_px
            + tc.sigma_gate * math.hypot(sigma, noise(u, v))
            + (shift + turn * math.hypot(u - cu, v - cv))
            for (u, v), sigma in zip(px, pred.sigma_list, strict=True)
        ]
        reacquire = reacquire or sigma_xy > self.config.handoff.reacquire_sigma_m
        windows = not reacquire and max(gates) <= tc.max_half_size_px
        if spots is None and windows and isinstance(e, FrameObserved):
            det = self.config.detection
            bg = self.background or estimate_background(e.image, det)
            half = [[g, g] for g in gates]
            found = spot_rows_in_windows(e.image, px, half, det, bg)
            spot_px = [[col, row] for col, row, _, _ in found]
        else:
            spots = self.full_spots(e) if spots is None else spots
            spot_px = spots.pixels.tolist()
        if not spot_px:
            return TrackResult(expected=expected)
        if reacquire and spots is not None:  # (reacquiring always detects the full frame)
            pairs = self._reacquire(pred, spots, gates, pose, cov)
        else:
            d = [[math.hypot(u - a, v - b) for a, b in spot_px] for u, v in px]
            rows = pred.row_list
            sure, _ = unambiguous_pairs(
                d,
                bottleneck_assignment(d, gates),
                [g / tc.sigma_gate for g in gates],
                tc.ambiguity_log_ratio,
            )
            pairs = [(rows[k], s) for k, s in sure]
        self.last_rejected = None
        # A robot lifted and carried off still sees a few spots fall into some windows by
        # chance: a fix of a small share of the landmarks last matched is not taken (kidnap).
        # Of those, only the ones still surely lit count: landmarks darkened since (an LED
        # schedule moving the robot from many lit landmarks to a few) are not missing.
        need = (
            0.0
            if reacquire
            else self.config.fusion.min_matched_fraction
            * len(self._still_lit(self.last_matched, candidates))
        )
        used = self._fuse(filt, pairs, spot_px, pose, need) if len(pairs) >= 2 else ()
        rejected = None if used or self.last_rejected is None else self.last_rejected[2]
        return TrackResult(
            used, unexplained=not used and len(pred) >= 2, expected=expected, rejected=rejected
        )

    def relocalize(
        self,
        filt: PoseFilter,
        spots: Spots,
        candidates: IntArray | None,
        *,
        prior: tuple[tuple[float, float, float], FloatArray] | None = None,
        hypotheses: HypothesisSet | None = None,
        t_ns: int = 0,
        odometry_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
        miss_weights: FloatArray | None = None,
    ) -> PoseFix | None:
        """Re-localization without LEDs around a prior (default: the filter's pose and
        covariance): one frame (`relocalization.relocalize`), or, given `hypotheses`, the
        set carried over frames (`HypothesisSet.update` with the frame's time and raw
        odometry pose). `miss_weights` (one per map row) is what each landmark's absence
        weighs (`LandmarkLiveness.miss_log_lr`). Returns the fix of the one unambiguous
        hypothesis, or None."""
        rows = np.arange(len(self.map.positions)) if candidates is None else candidates
        if len(rows) < 2 or len(spots) < 2:
            return None
        pose, cov = prior if prior is not None else (filt.pose, filt.covariance)
        cov = cov + np.diag([1e-4, 1e-4, 1e-4])
        rc = self.config.relocalization
        # only the landmarks that could be in view of a pose within the prior's gate
        reach = self._reach + math.sqrt(rc.prior_gate_chi2) * position_sigma_m(cov)
        P = self.map.positions[rows]
        if hypotheses is None:  # (the set keeps per-landmark evidence: the same rows always)
            rows = rows[np.hypot(P[:, 0] - pose[0], P[:, 1] - pose[1]) <= reach]
        if len(rows) < 2:
            return None
        positions = self.map.positions[rows]
        weights = None if miss_weights is None else miss_weights[rows]
        if hypotheses is None:
            found = relocalize(self.camera, positions, spots.pixels, pose, cov, rc, weights)
        else:
            found = hypotheses.update(
                t_ns, odometry_pose, self.camera, positions, spots.pixels, pose, cov, weights
            )
        if not found.accepted or found.pose is None:
            return None
        pairs = [(int(rows[r]), s) for r, s in found.pairs]
        fc = self.config.fusion
        px = spots.pixels[[s for _, s in pairs]].tolist()
        rows_used = [r for r, _ in pairs]
        sig = self._spot_sigmas(rows_used, px)
        fix = self._solve(rows_used, px, sig, found.pose, robust=True)
        if fix is None or fix.n_landmarks < 2:
            return None
        fix = self._with_calibration(fix, rows_used, px, sig)
        res = fix.residuals_px or (fix.residual_rms_px,) * len(sig)
        inliers = sum(1 for r, si in zip(res, sig, strict=True) if r <= fc.outlier_sigma * si)
        if inliers < max(2, 0.8 * len(sig)):
            return None
        return fix

    def _reacquire(
        self,
        pred: Prediction,
        spots: Spots,
        gates: list[float],
        pose: tuple[float, float, float],
        cov: tuple[list[float], list[float], list[float]],
    ) -> list[tuple[int, int]]:
        """A hand-off after long dead reckoning: the one map-consistent hypothesis, or none."""
        hc = self.config.handoff
        hyps = consistent_hypotheses(self.camera, pred, self.map.positions, spots.pixels, gates, hc)
        if not hyps:
            return []
        size = len(hyps[0])
        prior_cov = np.array(cov) + np.diag([1e-4, 1e-4, 1e-4])
        passing = [
            h
            for h in hyps
            if len(h) == size
            and pose_mahalanobis2(
                hypothesis_pose(self.camera, self.map.positions, spots.pixels, h), pose, prior_cov
            )
            <= hc.prior_gate_chi2
        ]
        return passing[0] if len(passing) == 1 else []

    def _still_lit(
        self, landmark_ids: frozenset[int], candidates: IntArray | None
    ) -> frozenset[int]:
        """The landmarks among `landmark_ids` that are surely lit (`candidates`: map rows of
        those; None: every landmark)."""
        if candidates is None:
            return landmark_ids
        ids = self._ids
        return landmark_ids & frozenset(ids[r] for r in candidates.tolist())
