"""What a survey found: each landmark's position with its uncertainty, and what looks wrong."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from localizer.types import FloatArray, IntArray


@dataclass(frozen=True, eq=False)
class LandmarkEstimate:
    """One landmark after the survey.

    Attributes:
        id: landmark ID.
        position: (x, y, z), metres, world frame.
        covariance: of the position, shape (3, 3), m^2 (zeros for an anchor).
        anchor: held at its given position (it fixes the map's frame).
        observations: spot observations used; views: keyframes that saw it.
        rms_px, max_px: reprojection residuals of its observations, pixels.
        given: the position the map held before (None: none), metres.
        flags: what looks wrong, in words (empty when nothing does).
    """

    id: int
    position: FloatArray
    covariance: FloatArray
    anchor: bool
    observations: int
    views: int
    rms_px: float
    max_px: float
    given: FloatArray | None = None
    flags: tuple[str, ...] = ()

    @property
    def sigma_xy_m(self) -> float:
        """1-sigma horizontal uncertainty, metres: the larger semi-axis of the ellipse."""
        return math.sqrt(max(float(np.linalg.eigvalsh(self.covariance[:2, :2])[-1]), 0.0))

    @property
    def sigma_z_m(self) -> float:
        """1-sigma height uncertainty, metres."""
        return math.sqrt(max(float(self.covariance[2, 2]), 0.0))

    @property
    def sigma_m(self) -> float:
        """1-sigma position uncertainty, metres: the largest semi-axis of the 3-D ellipsoid."""
        return math.sqrt(max(float(np.linalg.eigvalsh(self.covariance)[-1]), 0.0))

    def ellipse(self) -> tuple[float, float, float]:
        """The horizontal 1-sigma ellipse: (major m, minor m, angle of the major axis rad)."""
        w, v = np.linalg.eigh(self.covariance[:2, :2])
        return (
            math.sqrt(max(float(w[1]), 0.0)),
            math.sqrt(max(float(w[0]), 0.0)),
            math.atan2(float(v[1, 1]), float(v[0, 1])),
        )


@dataclass(frozen=True, eq=False)
class SurveyResult:
    """The survey's estimate.

    Attributes:
        landmarks: by ID, every landmark that was seen (anchors included).
        unseen: landmarks of the map the survey could not place: never identified, or seen
            from fewer than `BundleConfig.min_views` independent views.
        trajectory_t_ns: keyframe times, shape (K,); trajectory: body poses there
            (x, y, theta), shape (K, 3).
        wheel_calibration: (left scale, right scale, wheel-base scale), 1 = nominal.
        camera_correction: (fu scale - 1, fv scale - 1, cu offset px, cv offset px, mounting
            yaw rad, change of the first distortion coefficient k1, mounting roll rad, pitch
            rad, camera height m, change of k2); zeros when not self-calibrated.
        rms_px: reprojection RMS over all observations, pixels.
        sigma_scale: the spots' a-posteriori standard deviation of unit weight (their noise
            as the residuals show it, in units of `BundleConfig.pixel_sigma_px`): the factor
            their information was scaled by for the covariances.
        iterations: solver function evaluations; converged: the solver's own verdict.
        unnamed: why each landmark in `unseen` was not placed, in words (too close to a
            neighbour for its rough position, never in view, ...).
    """

    landmarks: dict[int, LandmarkEstimate]
    unseen: tuple[int, ...]
    trajectory_t_ns: IntArray
    trajectory: FloatArray
    wheel_calibration: tuple[float, float, float]
    camera_correction: tuple[float, ...]
    rms_px: float
    sigma_scale: float
    iterations: int
    converged: bool
    notes: tuple[str, ...] = field(default=())
    unnamed: dict[int, str] = field(default_factory=dict)

    def flagged(self) -> list[LandmarkEstimate]:
        """Landmarks with a flag, worst first."""
        out = [e for e in self.landmarks.values() if e.flags]
        return sorted(out, key=lambda e: -e.rms_px)
