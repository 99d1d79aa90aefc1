"""What the survey estimates from (`SurveyProblem`) and how (`BundleConfig`): the inputs of
`survey.bundle.solve_survey`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from localizer.camera import CameraModel
from localizer.types import FloatArray, IntArray
from survey.observations import LabelledObservations


@dataclass(frozen=True)
class BundleConfig:
    """Tuning of the survey's estimator (SI units).

    Attributes:
        keyframe_period_s: at most one keyframe per this interval (frames in between add
            little but time).
        pixel_sigma_px: standard deviation of a spot centre per axis, pixels.
        huber_scale: residual (in sigmas) beyond which the Huber loss grows linearly.
        odom_sigma_m_per_sqrt_m, odom_sigma_floor_m: translation noise of the wheels over an
            interval: sqrt(floor^2 + a^2 * distance).
        odom_heading_sigma_rad_per_sqrt_m, odom_heading_sigma_rad_per_sqrt_rad,
        odom_heading_floor_rad: heading noise: sqrt(floor^2 + b^2 * distance + c^2 * turned).
        rough_sigma_m: standard deviation of a rough position from map.json, per axis (a
            tape or a floor plan off by up to ~30 cm: 15 cm).
        anchor_sigma_m: standard deviation of an anchor's surveyed position, per axis (a
            total station: about a millimetre).
        wheel_scale_sigma: prior standard deviation of each wheel calibration factor.
        self_calibrate: estimate the camera correction too.
        focal_sigma_rel, principal_sigma_px, mount_yaw_sigma_rad: its priors;
        mount_tilt_sigma_rad, mount_height_sigma_m: of the mounting's roll and pitch, and
            of its height (what the mounting calibration or a tape leaves);
        distortion_sigma_rel: the first two distortion coefficients', relative to each.
        max_iterations: Gauss-Newton steps of the final solve, at most.
        window_s: the drive is solved in windows from its start: this long, then twice as
            long, and so on, seconds.
        window_iterations: the same for each window's solve.
        outlier_track_px: a spot track whose median reprojection error exceeds this is set
            aside (misnamed, or its landmark moved), pixels.
        min_votes: blink votes a track's name needs to be used at once; tracks with fewer
            (or none) are named when the solution agrees (`name_radius_m`).
        name_radius_m: a track whose spots meet the ceiling this close to a landmark's
            estimate may take its name.
        name_exclusion_m: ... if no other landmark is this close (unnamed tracks).
        associate: name tracks no blink named by map-consistent association
            (`survey.association`): where a landmark's rough position is good enough.
        ceiling_sigma_m: how far a landmark's height may be from the anchors' (1 sigma), for
            placing unnamed spots on the ceiling, metres.
        association_gate_chi2: a spot cluster farther than this (Mahalanobis^2, 2 dof) from
            a landmark cannot be it (18.4: the 1e-4 tail).
        association_margin_chi2: a cluster is named only if every other explanation costs
            this much more (13.8: odds of 1000 to one).
        naming_rounds: solves per window at most while tracks are being named.
        independent_view_m: views of a landmark closer than this (robot travel) count as one
            (`min_views`).
        flag_rms_px: a landmark whose residual RMS exceeds this is flagged (moved during the
            drive, or two landmarks answering to one name).
        flag_moved_m: a landmark this far from its given position is flagged (moved, or
            radios swapped).
        min_views: a landmark seen in fewer independent views is not placed (it is reported
            with the unseen ones).
    """

    keyframe_period_s: float = 0.2
    pixel_sigma_px: float = 0.5
    huber_scale: float = 3.0
    odom_sigma_m_per_sqrt_m: float = 0.01
    odom_sigma_floor_m: float = 0.001
    odom_heading_sigma_rad_per_sqrt_m: float = 0.005
    odom_heading_sigma_rad_per_sqrt_rad: float = 0.02
    odom_heading_floor_rad: float = 0.001
    rough_sigma_m: float = 0.15
    anchor_sigma_m: float = 0.001
    wheel_scale_sigma: float = 0.01
    self_calibrate: bool = True
    focal_sigma_rel: float = 0.002
    principal_sigma_px: float = 2.0
    mount_yaw_sigma_rad: float = math.radians(1.0)
    mount_tilt_sigma_rad: float = 0.002
    mount_height_sigma_m: float = 0.005
    distortion_sigma_rel: float = 0.1
    max_iterations: int = 30
    window_s: float = 30.0
    window_iterations: int = 8
    outlier_track_px: float = 6.0
    min_votes: int = 1
    name_radius_m: float = 0.05
    name_exclusion_m: float = 0.25
    associate: bool = True
    ceiling_sigma_m: float = 0.05
    association_gate_chi2: float = 18.42
    association_margin_chi2: float = 13.8
    naming_rounds: int = 8
    independent_view_m: float = 0.25
    flag_rms_px: float = 2.0
    flag_moved_m: float = 0.5
    min_views: int = 3


@dataclass(frozen=True, eq=False)
class SurveyProblem:
    """Everything the survey estimates from.

    Attributes:
        camera: the surveying camera (as calibrated).
        wheel_base_m: nominal wheel base, metres.
        frame_t_ns: frame times, shape (F,).
        observations: named spots (`survey.observations.label_spot_tracks`).
        odom_t_ns, odom_v: wheel speeds (v_left, v_right) m/s at their times, (N,), (N, 2).
        anchors: landmark id -> surveyed position (3,), metres; two or more.
        given: every other landmark to survey -> its rough position (3,) or None.
    """

    camera: CameraModel
    wheel_base_m: float
    frame_t_ns: IntArray
    observations: LabelledObservations
    odom_t_ns: IntArray
    odom_v: FloatArray
    anchors: dict[int, FloatArray]
    given: dict[int, FloatArray | None] = field(default_factory=dict)
