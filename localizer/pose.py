"""The robot's pose from identified ceiling landmarks (paper Sec. III-B): `solve_pose`.

Least squares over every identified landmark, with each landmark's own height and the real
camera mounting (offset, yaw, mounting tilt), optionally also the body's tilt (roll, pitch).
Each spot is undistorted once; its ray meets the landmark's height plane in a body-frame
point, and the pose is the weighted 2D registration of those points onto the map, each
residual whitened by the pixel noise mapped through the lens and the ray (`pose_planar`): to
first order the reprojection error in pixels. It starts from a closed form (weighted 2D
Procrustes, for two landmarks the paper's eqs. (1)-(2) generalised), which is exact for
noise-free pixels without tilt. Its steps are `pose_steps`; its tuning `PoseSolveConfig`
(`pose_config`); the paper's own closed form, the baseline, is `pose_paper`.

Frames: see docs/conventions.md and docs/estimation.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel
from localizer.geometry import wrap_angle
from localizer.pose_config import PoseSolveConfig
from localizer.pose_steps import (
    fit_on_carried_floor,
    fit_zero_mean_tilt,
    level_fit,
    rays_on_landmark_planes,
)
from localizer.types import FloatArray

_LEVEL = PoseSolveConfig()  # the default: a level least-squares fit


@dataclass(frozen=True, eq=False)
class PoseFix:
    """One pose measurement from the landmarks seen in one frame.

    Attributes:
        x, y: body position (axle midpoint on the floor), metres, world frame.
        theta: REP-103 heading, radians in (-pi, pi].
        covariance: of (x, y, theta), shape (3, 3), SI units (tilt marginalised out).
        tilt: body (roll, pitch), radians, shape (2,); zeros unless estimated.
        residual_rms_px: root mean square of the landmarks' reprojection errors, pixels
            (sqrt of the mean over landmarks of the squared pixel distance).
        landmark_ids: the landmarks used, in the order given.
        n_landmarks: how many landmarks were used.
        residuals_px: each landmark's reprojection error, pixels (empty when the tilted
            fit of the zero-mean test was taken; a fix solved with a tilt prior has them).
        floor: (roll, pitch, dz) when solved with a floor prior (None otherwise): the tilt
            and the body's height above the map's floor, metres.
        floor_covariance: their posterior covariance when the fix estimated them, shape
            (3, 3) (the carried floor's update, `floor_plane`), else None.
        floor_cross: then the covariance of (x, y, theta) with them, shape (3, 3).
        floor_sensitivity: then, when solved with a `calibration_jacobian`, what of the
            calibration's error the floor holds: d floor / d c per standard deviation of
            each calibration parameter, shape (3, Q) (`pose_tilted.floor_change_chi2`'s E).
    """

    x: float
    y: float
    theta: float
    covariance: FloatArray
    tilt: FloatArray = field(default_factory=lambda: np.zeros(2))
    residual_rms_px: float = 0.0
    landmark_ids: tuple[int, ...] = ()
    n_landmarks: int = 0
    residuals_px: tuple[float, ...] = ()
    floor: FloatArray | None = None
    floor_covariance: FloatArray | None = None
    floor_cross: FloatArray | None = None
    floor_sensitivity: FloatArray | None = None

    def plus_covariance_turned(self, term: FloatArray, turn_rad: float) -> PoseFix:
        """This fix with `term` (3, 3), turned about the vertical by `turn_rad`
        (R term R^T), added to its covariance (plain floats: the tracking hot path)."""
        c, s = math.cos(turn_rad), math.sin(turn_rad)
        (a0, a1, a2), (b0, b1, b2), (g0, g1, g2) = term.tolist()
        # R C: rows 0 and 1 turned, row 2 as it is; then (R C) R^T added, row by row
        RC = (
            (c * a0 - s * b0, c * a1 - s * b1, c * a2 - s * b2),
            (s * a0 + c * b0, s * a1 + c * b1, s * a2 + c * b2),
            (g0, g1, g2),
        )
        cov = np.array(
            [
                [p0 + c * r0 - s * r1, p1 + s * r0 + c * r1, p2 + r2]
                for (p0, p1, p2), (r0, r1, r2) in zip(self.covariance.tolist(), RC, strict=True)
            ]
        )
        return PoseFix(
            self.x,
            self.y,
            self.theta,
            cov,
            self.tilt,
            self.residual_rms_px,
            self.landmark_ids,
            self.n_landmarks,
            self.residuals_px,
            self.floor,
            self.floor_covariance,
            self.floor_cross,
            self.floor_sensitivity,
        )


def solve_pose(
    camera: CameraModel,
    pixels: npt.ArrayLike,
    p_world: npt.ArrayLike,
    *,
    config: PoseSolveConfig = _LEVEL,
    initial: PoseFix | tuple[float, float, float] | None = None,
    pixel_sigma_px: float | Sequence[float] = 0.3,
    landmark_ids: tuple[int, ...] = (),
    floor_prior: tuple[tuple[float, float, float], FloatArray] | None = None,
    calibration_jacobian: Callable[[list[list[float]]], FloatArray] | None = None,
    floor_sensitivity: FloatArray | None = None,
) -> PoseFix | None:
    """Least-squares body pose from two or more identified landmarks.

    Minimises sum_i |G_i^-1 (q_i - Rz(theta)^T (P_i,xy - t))|^2 / sigma^2 (see `pose_planar`):
    q_i is where landmark i's ray meets its height plane (body frame, or the level frame when
    the body is tilted), G_i = d q_i / d pixel, so each term is, to first order, landmark i's
    reprojection error in pixels over the pixel noise. Gauss-Newton; the covariance is
    (J^T J)^-1 of the whitened problem, the pose block (tilt marginalised out).

    Args:
        camera: lens and mounting (`camera.T_body_camera`).
        pixels: measured spot centres (col, row), shape (N, 2), distorted (raw) pixels.
        p_world: the landmarks' world positions, shape (N, 3), metres (own heights).
        config: the fit's tuning (`PoseSolveConfig`: whether to test a tilt, the robust
            loss, the iterations); default a level least-squares fit.
        initial: a starting pose (a previous fix, or (x, y, theta)); without it the solver
            starts from the closed form.
        pixel_sigma_px: standard deviation of a spot centre per axis, pixels: one for all,
            or one per landmark (e.g. growing with the radius, `noise_model`).
        landmark_ids: IDs to carry into the fix.
        floor_prior: a prior on the body's tilt and height above the map's floor,
            ((roll, pitch radians, dz metres), covariance (3, 3)): the floor carried from
            earlier fixes (`floor_plane`). Given, the level fit is solved on that floor (at
            the prior's tilt and height), and the tilt test is made around it: with 3+
            landmarks and `config.estimate_tilt` the tilted fit (tilt and height too, the
            prior's Bayesian update, robust by the carried fit's weights) is taken when it
            lowers the chi-square by more than `config.tilt_min_chi2_drop`; then `floor` and
            `floor_covariance` are its posterior. Otherwise `floor` is the prior's mean and
            `floor_covariance` None (the floor carried; its uncertainty, common to the
            frames on it, is not added to the fix's, as the level floor's never was).
        calibration_jacobian: with `floor_prior`, the function of the spots' pixels (N, 2)
            giving d pixel / d calibration of each, times the calibration's standard
            deviations, shape (N, 2, Q) (`PixelNoiseModel.calibration_jacobian`; called only
            when the test below needs it). Given, the tilted fit's floor is also
            taken only when its change from the prior's is significant against what pixel
            noise and the calibration's error make of it (`floor_change_chi2` above
            `tilt_min_chi2_drop`): a calibration's error displaces a dense grid's spots
            coherently, partly like a tilt and a height, and the chi-square drop of pixel
            noise alone grows with the number of landmarks; the calibration's share of the
            floor's spread does not shrink with it.
        floor_sensitivity: what of the calibration's error the prior's floor holds, shape
            (3, Q) (`FloorPlane.sensitivity_at`; None: none), for that test.

    Returns:
        The fix, or None when degenerate: fewer than 2 landmarks, coincident landmarks, a
        landmark not above the camera, a singular problem or no convergence.

    Raises:
        ValueError: when `pixels` and `p_world` have mismatched or wrong shapes.
    """
    rays = rays_on_landmark_planes(camera, pixels, p_world, config.min_separation_px, floor_prior)
    if rays is None:
        return None
    start: tuple[float, float, float] | None
    if initial is None:
        start = None
    elif isinstance(initial, PoseFix):
        start = (initial.x, initial.y, initial.theta)
    else:
        start = (float(initial[0]), float(initial[1]), float(initial[2]))
    fit = level_fit(rays, start, pixel_sigma_px, config)
    if fit is None:
        return None
    # Tilt only when the data demand it: the level fit's chi-square must drop by more than
    # `tilt_min_chi2_drop` (a likelihood-ratio test, 2 dof). The drop cannot exceed the level
    # fit's own chi-square, so a consistent level fit skips the tilted solve altogether.
    test = config.estimate_tilt and rays.n >= 3 and fit.chi2 > config.tilt_min_chi2_drop
    if floor_prior is not None:
        fit = fit_on_carried_floor(
            rays, fit, floor_prior, test, config, calibration_jacobian, floor_sensitivity
        )
    elif test:
        tilt0 = initial.tilt if isinstance(initial, PoseFix) else (0.0, 0.0)
        fit = fit_zero_mean_tilt(rays, fit, tilt0, config)
    return PoseFix(
        x=fit.x,
        y=fit.y,
        theta=float(wrap_angle(fit.theta)),
        covariance=fit.covariance,
        tilt=fit.tilt,
        residual_rms_px=fit.rms,
        landmark_ids=tuple(map(int, landmark_ids)),
        n_landmarks=rays.n,
        residuals_px=fit.residuals,
        floor=fit.floor,
        floor_covariance=fit.floor_covariance,
        floor_cross=fit.floor_cross,
        floor_sensitivity=fit.floor_sensitivity if fit.floor_covariance is not None else None,
    )
