"""`solve_pose`'s steps (`pose`): the rays, the level fit, the tilt test.

1. `rays_on_landmark_planes`: the spots checked, undistorted once with their Jacobians, and
   their rays met with the landmarks' height planes (on a carried floor's tilt and height
   when one is given): the body-frame points of the planar problem (`pose_planar`).
2. `level_fit`: the level (or carried-floor) planar fit, from the closed form (weighted 2D
   Procrustes) or a start pose.
3. The tilt test, a likelihood-ratio test on the chi-square: on a carried floor
   (`fit_on_carried_floor`: the tilted fit with the carried floor as its prior, also
   checked against the calibration's error), or without one (`fit_zero_mean_tilt`: roll
   and pitch with an optional zero-mean prior), each taken only when the spots demand it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, normalized_from_pixels
from localizer.pose_config import PoseSolveConfig
from localizer.pose_planar import (
    ROBUST_WEIGHTS,
    Mat2,
    Point,
    floor_points,
    procrustes_2d,
    solve_planar,
)
from localizer.pose_tilted import floor_change_chi2, level_mounting, solve_tilted
from localizer.types import FloatArray

_JACOBIAN_STEP_PX = 0.5  # forward-difference step for d(normalised)/d(pixel)


@dataclass(frozen=True, slots=True)
class Rays:
    """The spots undistorted and carried to their landmarks' height planes (body frame).

    pl, Pl: the pixels (N, 2) and world positions (N, 3) as nested lists; m: normalised
    image coordinates; A: d m / d pixel per spot (a 2x2 as 4 floats); q: the body-frame
    points where the rays meet the height planes; G: d q / d pixel; P_xy: the landmarks'
    map (x, y); heights: their z.
    """

    pl: list[list[float]]
    Pl: list[list[float]]
    m: list[Point]
    A: list[Mat2]
    q: list[Point]
    G: list[Mat2]
    P_xy: list[Point]
    heights: list[float]
    T_body_camera: FloatArray

    @property
    def n(self) -> int:
        return len(self.pl)

    def tilted_fit(
        self,
        start: tuple[float, ...],
        sigma_px: float | Sequence[float],
        tilt_sigma_rad: float | None,
        max_iterations: int,
        *,
        floor_prior: tuple[tuple[float, float, float], FloatArray] | None = None,
    ) -> tuple[list[float], FloatArray, float, list[float]] | None:
        """`solve_tilted` on these rays (the same arguments after the rays)."""
        m, A, z, P, T = self.m, self.A, self.heights, self.P_xy, self.T_body_camera
        return solve_tilted(
            m, A, z, P, T, start, sigma_px, tilt_sigma_rad, max_iterations, floor_prior=floor_prior
        )


@dataclass(slots=True)
class Fit:
    """A fit on its way to a `pose.PoseFix`: the pose, its covariance and what the tests need
    (`chi2` and `sigmas` are the level fit's, per landmark)."""

    x: float
    y: float
    theta: float
    covariance: FloatArray
    rms: float
    residuals: tuple[float, ...]
    chi2: float
    sigmas: list[float]
    raw_residuals: list[float]
    tilt: FloatArray
    floor: FloatArray | None = None
    floor_covariance: FloatArray | None = None
    floor_cross: FloatArray | None = None
    floor_sensitivity: FloatArray | None = None


def rays_on_landmark_planes(
    camera: CameraModel,
    pixels: npt.ArrayLike,
    p_world: npt.ArrayLike,
    min_separation_px: float,
    floor_prior: tuple[tuple[float, float, float], FloatArray] | None,
) -> Rays | None:
    """Step 1: the inputs checked, undistorted once with their Jacobians, and the rays met
    with the landmarks' height planes (on the carried floor's tilt and height when given).
    None when degenerate (fewer than 2, not finite, coincident, a landmark not above)."""
    if isinstance(pixels, list) and isinstance(p_world, list):
        # nested lists (the tracking hot path): checked as they are, no round trip through numpy
        pl, Pl = pixels, p_world
        if len(Pl) != len(pl) or any(len(p) != 2 for p in pl) or any(len(p) != 3 for p in Pl):
            shapes = [len(p) for p in pl], [len(p) for p in Pl]
            raise ValueError(f"solve_pose: pixels must be (N, 2) and p_world (N, 3), got {shapes}")
    else:
        px = np.asarray(pixels, dtype=np.float64)
        P = np.asarray(p_world, dtype=np.float64)
        if px.ndim != 2 or px.shape[1] != 2 or P.shape != (len(px), 3):
            raise ValueError(
                f"solve_pose: pixels must be (N, 2) and p_world (N, 3), got {px.shape} and "
                f"{P.shape}"
            )
        pl, Pl = px.tolist(), P.tolist()
    n = len(pl)
    # a sum is finite only if every term is (inf - inf is nan)
    if n < 2 or not math.isfinite(sum(map(sum, pl)) + sum(map(sum, Pl))):
        return None
    min_sep2 = min_separation_px**2
    for i in range(n):
        for j in range(i + 1, n):
            if (pl[i][0] - pl[j][0]) ** 2 + (pl[i][1] - pl[j][1]) ** 2 < min_sep2:
                return None
    # Undistort the pixels and two offset copies in one call: m and A = d m / d pixel.
    h = _JACOBIAN_STEP_PX
    shifted = pl + [[c + h, r] for c, r in pl] + [[c, r + h] for c, r in pl]
    nl = normalized_from_pixels(camera, shifted).tolist()
    m = nl[:n]
    A = [
        ((ux - mx) / h, (vx - mx) / h, (uy - my) / h, (vy - my) / h)
        for (mx, my), (ux, uy), (vx, vy) in zip(m, nl[n : 2 * n], nl[2 * n :], strict=True)
    ]
    mounting: Sequence[Sequence[float]] = camera.T_body_camera_rows
    if floor_prior is not None:
        mounting = level_mounting(camera.T_body_camera, *floor_prior[0])
    heights = [p[2] for p in Pl]
    floor = floor_points(m, A, heights, mounting)
    if floor is None:
        return None
    q, G = floor
    P_xy = [(p[0], p[1]) for p in Pl]
    return Rays(pl, Pl, m, A, q, G, P_xy, heights, camera.T_body_camera)


def level_fit(
    rays: Rays,
    initial: tuple[float, float, float] | None,
    pixel_sigma_px: float | Sequence[float],
    config: PoseSolveConfig,
) -> Fit | None:
    """Step 2: the level (or carried-floor) planar fit from the closed form or `initial`
    (x, y, theta)."""
    q, G, P_xy = rays.q, rays.G, rays.P_xy
    if initial is None:
        weights = [
            1.0 / (g00 * g00 + g01 * g01 + g10 * g10 + g11 * g11) for g00, g01, g10, g11 in G
        ]
        start = procrustes_2d(q, P_xy, weights)
        if start is None:
            return None
    else:
        start = initial
    loss, loss_scale = config.loss, config.loss_scale
    planar = solve_planar(
        q, G, P_xy, start, pixel_sigma_px, config.max_iterations, loss=loss, loss_scale=loss_scale
    )
    if planar is None:
        return None
    (x, y, theta), c, rms, res = planar
    n = rays.n
    sig = [pixel_sigma_px] * n if isinstance(pixel_sigma_px, int | float) else pixel_sigma_px
    chi2 = sum([(r / si) ** 2 for r, si in zip(res, sig, strict=True)])
    covariance = np.array([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]])
    return Fit(x, y, theta, covariance, rms, tuple(res), chi2, list(sig), list(res), np.zeros(2))


def fit_on_carried_floor(
    rays: Rays,
    fit: Fit,
    floor_prior: tuple[tuple[float, float, float], FloatArray],
    test: bool,
    config: PoseSolveConfig,
    calibration_jacobian: Callable[[list[list[float]]], FloatArray] | None,
    floor_sensitivity: FloatArray | None,
) -> Fit:
    """Step 3 with a carried floor: its fit (step 2's) unless the spots demand a floor of
    their own: the tilted fit with the carried floor as its prior must lower the chi-square
    by more than `tilt_min_chi2_drop` (the likelihood-ratio test of the zero-mean case,
    around the carried floor instead of the level one), and, given the calibration's
    Jacobian, its floor's change must be significant against the calibration's error too."""
    loss, loss_scale = config.loss, config.loss_scale
    tilt_min_chi2_drop, max_iterations = config.tilt_min_chi2_drop, config.max_iterations
    e0, _ = floor_prior
    fit.floor = np.array(e0, dtype=np.float64)
    fit.tilt = fit.floor[:2].copy()
    if not test:
        return fit
    sig, res = fit.sigmas, fit.raw_residuals
    # the carried fit's robust weights kept: sigma_i / sqrt(w_i)
    w = [
        ROBUST_WEIGHTS[loss](r / si, loss_scale) if loss else 1.0
        for r, si in zip(res, sig, strict=True)
    ]
    sig_w = [si / math.sqrt(wi) for si, wi in zip(sig, w, strict=True)]
    start = (fit.x, fit.y, fit.theta, *e0)
    tilted = rays.tilted_fit(start, sig_w, None, max_iterations, floor_prior=floor_prior)
    if tilted is None:
        return fit
    params, cov_full, rms_t, res_t = tilted
    chi2_t = sum((r / si) ** 2 for r, si in zip(res_t, sig, strict=True))
    take = tilt_min_chi2_drop <= 0 or fit.chi2 - chi2_t > tilt_min_chi2_drop
    if take and calibration_jacobian is not None:
        change, fit.floor_sensitivity = floor_change_chi2(
            rays.m,
            rays.A,
            rays.heights,
            rays.P_xy,
            rays.T_body_camera,
            params,
            cov_full,
            sig_w,
            floor_prior,
            calibration_jacobian(rays.pl),
            floor_sensitivity,
        )
        # nan (degenerate): as without
        take = tilt_min_chi2_drop <= 0 or not change <= tilt_min_chi2_drop
    if take:
        fit.x, fit.y, fit.theta = params[0], params[1], params[2]
        fit.covariance, fit.rms = cov_full[:3, :3].copy(), rms_t
        fit.floor, fit.floor_covariance = np.array(params[3:6]), cov_full[3:6, 3:6].copy()
        fit.floor_cross = cov_full[:3, 3:6].copy()
        fit.tilt = fit.floor[:2].copy()
        fit.residuals = tuple(res_t)
    return fit


def fit_zero_mean_tilt(
    rays: Rays,
    fit: Fit,
    tilt0: Sequence[float] | FloatArray,
    config: PoseSolveConfig,
) -> Fit:
    """Step 3 without a carried floor: the tilted fit (roll, pitch; an optional zero-mean
    prior) taken when it lowers the level fit's chi-square by more than
    `tilt_min_chi2_drop`."""
    tilt_sigma_rad, tilt_min_chi2_drop = config.tilt_sigma_rad, config.tilt_min_chi2_drop
    max_iterations = config.max_iterations
    n = rays.n
    sigma_px = math.sqrt(sum([si * si for si in fit.sigmas]) / n)
    roll0, pitch0 = (float(v) for v in tilt0)
    start = (fit.x, fit.y, fit.theta, roll0, pitch0)
    tilted = rays.tilted_fit(start, sigma_px, tilt_sigma_rad, max_iterations)
    if tilted is None:
        return fit
    params, cov_full, rms_tilted, _ = tilted
    drop = fit.chi2 - n * (rms_tilted / sigma_px) ** 2
    if tilt_min_chi2_drop <= 0 or drop > tilt_min_chi2_drop:
        fit.x, fit.y, fit.theta = params[0], params[1], params[2]
        fit.covariance, fit.tilt = cov_full[:3, :3].copy(), np.array(params[3:5])
        fit.rms = rms_tilted
        fit.residuals = ()
    return fit
