"""One tracking step with a known pose (Sec. IV-A): predict, search, assign, solve, fuse.

Eq. (3) predicts the lit landmarks' pixels from the filter's pose; spots are searched in
windows sized from speed, frame interval, scale, radius and uncertainty (Sec. IV-A.1) and
assigned by the bottleneck rule; after long dead reckoning (or when asked) only a hypothesis
that agrees with the map's geometry is taken (eq. 4 with a geometric check). `solve_pose`
over every matched landmark (tilt too with 3+), gated by the residual and the normalised
innovation, is fused by `PoseFilter.update_fix`.

This is the localizer's hot path while tracking: small Python lists instead of numpy arrays
(for three landmarks numpy's per-call cost is most of the work), the windows searched
without a full-frame pass.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.events import FrameObserved, SpotsObserved
from localizer.handoff import (
    Prediction,
    consistent_hypotheses,
    hypothesis_pose,
    pose_mahalanobis2,
    position_sigma_m,
    predict_landmarks,
    visible_radius_m,
)
from localizer.landmark_map import LandmarkMap
from localizer.pose import solve_pose
from localizer.pose_filter import PoseFilter
from localizer.robot import RobotGeometry
from localizer.spot_windows import spot_rows_in_windows
from localizer.spots import Spots, detect_spots, estimate_background
from localizer.tracking import (
    bottleneck_assignment,
    default_angular_speed,
    motion_bound_px,
    scale_px_per_m,
)

FloatArray = npt.NDArray[np.float64]
Frame = FrameObserved | SpotsObserved


class TrackResult(NamedTuple):
    """What a tracking step found.

    Attributes:
        used: IDs of the landmarks whose fix was fused (empty: none).
        unexplained: spots were seen while 2+ landmarks were predicted, and no fix was
            fused (the localizer counts these toward getting lost).
        expected: IDs of the lit landmarks predicted inside the image, sorted.
    """

    used: tuple[int, ...] = ()
    unexplained: bool = False
    expected: tuple[int, ...] = ()


_NOTHING = TrackResult()


class LandmarkTracker:
    """Tracking and fusing for one camera, robot and map (see the module docstring).

    Args:
        camera, robot, config: as the `Localizer`'s.
        landmark_map: the map; `set_map` replaces it.

    Attributes:
        scale_px_per_m: image scale of the map's ceiling (focal length over its median
            height above the camera).
        max_angular_speed_rad_s: the robot's fastest turn.
        background: the last full frame's background (level, noise), counts; None before.
    """

    def __init__(
        self,
        camera: CameraModel,
        robot: RobotGeometry,
        config: LocalizerConfig,
        landmark_map: LandmarkMap,
    ) -> None:
        self.camera = camera
        self.robot = robot
        self.config = config
        self.max_angular_speed_rad_s = config.tracking.max_angular_speed_rad_s or (
            default_angular_speed(robot.max_speed, robot.wheel_base)
        )
        self.background: tuple[float, float] | None = None
        self.set_map(landmark_map)

    def set_map(self, landmark_map: LandmarkMap) -> None:
        """Track the landmarks of a new map."""
        self.map = landmark_map
        self._ids: list[int] = landmark_map.ids.tolist()
        heights = landmark_map.positions[:, 2] - self.camera.T_body_camera[2, 3]
        ceiling_m = float(np.median(heights)) if len(heights) else 2.2
        self.scale_px_per_m = scale_px_per_m(max(self.camera.fu, self.camera.fv), ceiling_m)
        self._reach = visible_radius_m(self.camera, float(np.max(heights, initial=ceiling_m)))

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
        candidates: npt.NDArray[np.int64] | None,
        spots: Spots | None = None,
        reacquire: bool = False,
    ) -> TrackResult:
        """Find the lit landmarks near their predictions, solve and fuse.

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
        """
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
        expected = tuple(sorted(self._ids[r] for r in pred.row_list))
        tc = self.config.tracking
        dt_free = dt_frame_s * (tc.odometry_speed_fraction if fresh_odometry else 1.0)
        px = pred.pixel_list
        cu, cv = self.camera.cu, self.camera.cv
        gates = [  # window half sizes and assignment gates, pixels
            tc.min_half_size_px
            + tc.sigma_gate * sigma
            + motion_bound_px(
                math.hypot(u - cu, v - cv),
                max_speed_m_s=self.robot.max_speed,
                max_angular_speed_rad_s=self.max_angular_speed_rad_s,
                dt_s=dt_free,
                scale_px_per_m=self.scale_px_per_m,
            )
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
            pairs = [(rows[k], s) for k, s in bottleneck_assignment(d, gates)]
        used = self._fuse(filt, pairs, spot_px, pose) if len(pairs) >= 2 else ()
        return TrackResult(used, unexplained=not used and len(pred) >= 2, expected=expected)

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

    def _fuse(
        self,
        filt: PoseFilter,
        pairs: list[tuple[int, int]],
        spot_px: list[list[float]],
        pose: tuple[float, float, float],
    ) -> tuple[int, ...]:
        """Solve the pose from matched (map row, spot) pairs; fuse it when consistent."""
        fc = self.config.fusion
        rows = [r for r, _ in pairs]
        px = [spot_px[s] for _, s in pairs]
        ids = tuple(self._ids[r] for r in rows)
        fix = solve_pose(
            self.camera,
            px,
            self.map.positions[rows],
            initial=pose,
            estimate_tilt=fc.tilt_from_landmarks and len(pairs) >= 3,
            tilt_sigma_rad=fc.tilt_sigma_rad,
            pixel_sigma_px=fc.pixel_sigma_px,
            landmark_ids=ids,
        )
        if fix is None or fix.residual_rms_px > fc.max_residual_px:
            return ()
        if not filt.update_fix(fix, max_nis=fc.nis_gate) <= fc.nis_gate:
            return ()
        return ids
