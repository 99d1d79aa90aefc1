"""`LocalizerConfig`: every tuning value of the localizer, grouped by stage, with units."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from localizer.constellation import ConstellationConfig
from localizer.filter_config import FilterConfig
from localizer.fix_run import FixRunConfig
from localizer.floor_plane import FloorPlaneConfig
from localizer.handoff import HandoffConfig
from localizer.identification_config import IdentificationConfig
from localizer.imu_tilt import ImuTiltConfig
from localizer.motion_model import MotionModelConfig
from localizer.noise_model import PixelNoiseConfig
from localizer.passive_config import PassiveConfig
from localizer.pose_planar import RobustLoss
from localizer.pose_quality import QualityConfig
from localizer.relocalization import RelocalizationConfig
from localizer.self_calibration import SelfCalibrationConfig
from localizer.spots import DetectionConfig
from localizer.tracking import TrackingConfig


@dataclass(frozen=True)
class FusionConfig:
    """Pose solving, fusion and the mode logic.

    Attributes:
        pixel_sigma_px: standard deviation of a spot's position per axis, pixels: centroid
            noise plus what the calibration leaves (solver weight and fix covariance; too
            small a value makes honest fixes fail the innovation gate).
        max_residual_px: a first fix (from identification) whose reprojection RMS exceeds
            this is inconsistent, pixels.
        robust_loss: the tracking fix's robust loss ("huber", "cauchy" or None: least
            squares), with 3+ landmarks.
        robust_scale: its threshold, in pixel sigmas (`LocalizerConfig.noise`).
        outlier_sigma: a landmark whose residual exceeds this many of its pixel sigmas is
            left out of the fix (the others are solved again).
        max_chi2_per_dof: a tracking fix whose chi-square per degree of freedom (2n - 3)
            exceeds this is inconsistent.
        nis_gate: a fix whose normalised innovation squared (3 dof) exceeds this is rejected
            (16.3 is the 99.9 % point of chi-square with 3 dof).
        tilt_from_landmarks: with 3+ landmarks also estimate the body tilt: with the floor's
            slope and height carried (`LocalizerConfig.floor`, the default) always, with the
            carried slope as its prior; without, taken only when it explains the spots
            significantly better (see `solve_pose`).
        tilt_sigma_rad: without the carried slope, the zero-mean prior on that tilt,
            radians (a tilt moves every spot almost like a translation, so an
            unconstrained one is noisy).
        lost_sigma_m: position standard deviation beyond which the localizer is lost, metres.
        lost_sigma_rad: heading standard deviation given to a pose the observations keep
            disagreeing with (a kidnapped robot may face anywhere), radians.
        lost_after_rejections: this many consecutive frames with spots seen while 2+
            landmarks are predicted in view but no accepted fix (observations that disagree
            with the map) make the localizer lost.
        carry_speed_m_s: how fast a robot may be moved without its odometry knowing
            (lifted and carried, pushed) while its observations go unexplained: on each frame
            of such a stretch the position uncertainty the spots are matched with is at
            least this x the stretch's duration (a put-down one grid spacing away must
            not be matched as the old pose), m/s. 0 (the default): off. On an independent
            recording (`bench/foreign` `stray_light`) a bad pairing among stray lights,
            absorbed by the tilted fit, left 0.7 s of unexplained frames while parked, and
            1 m/s turned them into a loss for good (docs/design/2026-12-02-kidnap-detection.md).
        min_matched_fraction: a tracking fix must keep at least this share of the
            landmarks of the last fused one that are still surely lit (a kidnapped robot,
            carried off, still sees a few spots fall into some windows by chance; such a fix
            is not fused; landmarks darkened since, as an LED schedule does, are not missing).
        initial_sigma_m: position standard deviation of `set_initial_pose`, metres.
        initial_sigma_rad: heading standard deviation of `set_initial_pose`, radians.
        odometry_history_s: how much raw odometry is kept to carry identification sightings
            to the current frame, seconds.
        odometry_interval_mean: an odometry sample is each wheel's mean speed over the
            interval since the previous one (docs/recording.md); False: instantaneous speeds
            (integrated by the trapezoid rule).
        odometry_stale_s: odometry older than this at a frame is stale: the whole frame
            interval counts as unpredicted motion, seconds.
        correlated_fix_error: a tracking fix's survey and calibration error is the same on
            every frame of the same landmarks: fuse it by the consider update of
            `fix_bias` (False: as white noise, every frame independent). See
            docs/localizer-models.md, "A fix's systematic error".
    """

    pixel_sigma_px: float = 1.0
    max_residual_px: float = 2.0
    robust_loss: RobustLoss | None = "huber"
    robust_scale: float = 2.0
    outlier_sigma: float = 4.0
    max_chi2_per_dof: float = 9.0
    nis_gate: float = 16.3
    tilt_from_landmarks: bool = True
    tilt_sigma_rad: float = 0.02
    lost_sigma_m: float = 1.0
    lost_sigma_rad: float = math.pi
    lost_after_rejections: int = 30
    carry_speed_m_s: float = 0.0
    min_matched_fraction: float = 0.25
    initial_sigma_m: float = 0.5
    initial_sigma_rad: float = 0.3
    odometry_history_s: float = 5.0
    odometry_interval_mean: bool = True
    odometry_stale_s: float = 0.2
    correlated_fix_error: bool = True


@dataclass(frozen=True)
class LocalizerConfig:
    """All tuning of `Localizer`, one sub-config per stage."""

    detection: DetectionConfig = field(default_factory=DetectionConfig)
    identification: IdentificationConfig = field(default_factory=IdentificationConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    handoff: HandoffConfig = field(default_factory=HandoffConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    filter: FilterConfig = field(default_factory=FilterConfig)
    relocalization: RelocalizationConfig = field(default_factory=RelocalizationConfig)
    noise: PixelNoiseConfig = field(default_factory=PixelNoiseConfig)
    self_calibration: SelfCalibrationConfig = field(default_factory=SelfCalibrationConfig)
    floor: FloorPlaneConfig = field(default_factory=FloorPlaneConfig)
    fix_run: FixRunConfig = field(default_factory=FixRunConfig)
    motion: MotionModelConfig = field(default_factory=MotionModelConfig)
    imu: ImuTiltConfig = field(default_factory=ImuTiltConfig)
    passive: PassiveConfig = field(default_factory=PassiveConfig)
    constellation: ConstellationConfig = field(default_factory=ConstellationConfig)
    quality: QualityConfig = field(default_factory=QualityConfig)
