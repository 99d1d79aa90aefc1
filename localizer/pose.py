"""The robot's pose from identified ceiling landmarks (paper Sec. III-B).

Two solvers:

* `pose_from_landmark_pair`: the paper's closed form, eqs. (1)-(2), kept as the baseline. It
  works in the image plane with one scale s = D/d and needs undistorted pixels, landmarks at
  one height and the camera on the axle. `pixels_from_pose_paper` is its inverse, the paper's
  eq. (3) with the bracket put where it belongs.
* `solve_pose`: the production solver. Least squares over every identified landmark, with
  each landmark's own height and the real camera mounting (offset, yaw, mounting tilt),
  optionally also the body's tilt (roll, pitch). Each spot is undistorted once; its ray meets
  the landmark's height plane in a body-frame point, and the pose is the weighted 2D
  registration of those points onto the map, each residual whitened by the pixel noise mapped
  through the lens and the ray (`pose_planar`): to first order the reprojection error in
  pixels. It starts from a closed form (weighted 2D Procrustes, for two landmarks the paper's
  eqs. (1)-(2) generalised), which is exact for noise-free pixels without tilt.

Frames: see docs/conventions.md and docs/estimation.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, normalized_from_pixels
from localizer.geometry import wrap_angle
from localizer.pose_planar import (
    ROBUST_WEIGHTS,
    Mat2,
    Point,
    floor_change_chi2,
    floor_points,
    level_mounting,
    procrustes_2d,
    solve_planar,
    solve_tilted,
)
from localizer.types import FloatArray

_JACOBIAN_STEP_PX = 0.5  # forward-difference step for d(normalised)/d(pixel)


# ---------------------------------------------------------------------------------------------
# The paper's closed form (baseline)


def pose_from_landmark_pair(
    px_i: npt.ArrayLike,
    px_j: npt.ArrayLike,
    P_i: npt.ArrayLike,
    P_j: npt.ArrayLike,
    image_center: npt.ArrayLike,
) -> tuple[float, float, float]:
    """Robot position and heading from two landmarks, the paper's eqs. (1)-(2).

    cos(theta) = (dx dX + dy dY) / (d D),  sin(theta) = (dx dY - dy dX) / (d D),   (1)
    (r_x, r_y) = s R(theta) ((c_x, c_y) - (x_i, y_i)) + (X_i, Y_i),  s = D / d,     (2)

    with (dx, dy) = p_j - p_i in the image, (dX, dY) = P_j - P_i in the world, d and D their
    lengths. theta is the rotation that turns image directions into world directions.

    Frame mapping (derived in docs/estimation.md). With OpenCV pixels (col, row) of an upward
    camera, the map from the image to the floor is a proper similarity (no mirror): the camera
    frame (x right, y down, z up) is right-handed with z along world z, so (col, row) turn into
    world (x, y) by a rotation. Only an image *displayed* with rows down and read as a map with
    y up looks mirrored. For the mounting `T_body_camera_upward(yaw=gamma)` the image's
    "up" direction (-row) is the robot's forward axis rotated by gamma, and the paper's theta
    relates to our REP-103 heading by heading = theta - gamma - pi/2 (see
    `heading_from_paper_angle`). (r_x, r_y) is the floor point under the optical centre: the
    robot's position only when the camera sits on the axle.

    Exact only for undistorted pixels of an ideal pinhole, both landmarks at one height, the
    optical axis vertical and `image_center` the principal point (cu, cv).

    Args:
        px_i, px_j: pixels (col, row) of landmarks i and j, shape (2,).
        P_i, P_j: their world positions, shape (2,) or (3,) (z is ignored), metres.
        image_center: (c_x, c_y), pixels.

    Returns:
        (r_x, r_y) metres and the paper's theta, radians in (-pi, pi].

    Raises:
        ValueError: when the two landmarks coincide in the image or in the world.
    """
    p_i, p_j = np.asarray(px_i, float)[:2], np.asarray(px_j, float)[:2]
    W_i, W_j = np.asarray(P_i, float)[:2], np.asarray(P_j, float)[:2]
    dx, dy = p_j - p_i
    dX, dY = W_j - W_i
    d, D = math.hypot(dx, dy), math.hypot(dX, dY)
    if d == 0.0 or D == 0.0:
        raise ValueError(f"pose_from_landmark_pair: landmarks coincide (d={d} px, D={D} m)")
    cos_t = (dx * dX + dy * dY) / (d * D)
    sin_t = (dx * dY - dy * dX) / (d * D)
    s = D / d
    R = np.array([[cos_t, -sin_t], [sin_t, cos_t]])
    r = s * R @ (np.asarray(image_center, float)[:2] - p_i) + W_i
    return float(r[0]), float(r[1]), float(wrap_angle(math.atan2(sin_t, cos_t)))


def heading_from_paper_angle(theta_paper: float, camera_yaw: float = 0.0) -> float:
    """REP-103 heading from the paper's theta, for `T_body_camera_upward(yaw=camera_yaw)`.

    heading = theta_paper - camera_yaw - pi/2, wrapped to (-pi, pi].
    """
    return float(wrap_angle(theta_paper - camera_yaw - 0.5 * math.pi))


def pixels_from_pose_paper(
    r_xy: npt.ArrayLike,
    theta_paper: float,
    scale: float,
    image_center: npt.ArrayLike,
    P_world: npt.ArrayLike,
) -> FloatArray:
    """Predicted pixels of landmarks, the paper's eq. (3) with its bracket corrected.

    (x_k', y_k') = (c_x, c_y) - (1/s) R(theta)^T ((r_x, r_y) - (X_k, Y_k)),

    the inverse of eq. (2). (The printed eq. (3) closes the bracket after (r_x, r_y), which
    subtracts a world position from a pixel.)

    Args:
        r_xy: (r_x, r_y), metres; theta_paper: radians; scale: s of eq. (2), metres/pixel.
        image_center: (c_x, c_y), pixels.
        P_world: landmark positions, shape (N, 2) or (N, 3) (z ignored).

    Returns:
        shape (N, 2), pixels.
    """
    c, s = math.cos(theta_paper), math.sin(theta_paper)
    Rt = np.array([[c, s], [-s, c]])
    P = np.asarray(P_world, dtype=np.float64)
    diff = np.asarray(r_xy, dtype=np.float64)[:2] - P.reshape(P.shape[0], -1)[:, :2]
    out: FloatArray = np.asarray(image_center, dtype=np.float64)[:2] - (diff @ Rt.T) / scale
    return out


# ---------------------------------------------------------------------------------------------
# The production solver


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
            each calibration parameter, shape (3, Q) (`pose_planar.floor_change_chi2`'s E).
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
        cov = np.array([
            [p0 + c * r0 - s * r1, p1 + s * r0 + c * r1, p2 + r2]
            for (p0, p1, p2), (r0, r1, r2) in zip(self.covariance.tolist(), RC, strict=True)
        ])  # fmt: skip
        return PoseFix(self.x, self.y, self.theta, cov, self.tilt, self.residual_rms_px,
                       self.landmark_ids, self.n_landmarks, self.residuals_px,
                       self.floor, self.floor_covariance, self.floor_cross,
                       self.floor_sensitivity)  # fmt: skip


def solve_pose(
    camera: CameraModel,
    pixels: npt.ArrayLike,
    p_world: npt.ArrayLike,
    *,
    initial: PoseFix | tuple[float, float, float] | None = None,
    estimate_tilt: bool = False,
    pixel_sigma_px: float | Sequence[float] = 0.3,
    landmark_ids: tuple[int, ...] = (),
    tilt_sigma_rad: float | None = None,
    floor_prior: tuple[tuple[float, float, float], FloatArray] | None = None,
    calibration_jacobian: Callable[[list[list[float]]], FloatArray] | None = None,
    floor_sensitivity: FloatArray | None = None,
    loss: str | None = None,
    loss_scale: float = 2.0,
    tilt_min_chi2_drop: float = 9.21,
    min_separation_px: float = 2.0,
    max_iterations: int = 20,
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
        initial: a starting pose (a previous fix, or (x, y, theta)); without it the solver
            starts from the closed form.
        estimate_tilt: with 3+ landmarks also consider a tilted body (roll, pitch), and use
            it when it explains the spots significantly better (see `tilt_min_chi2_drop`);
            ignored with fewer landmarks. Tilt and translation are nearly interchangeable for
            a small cluster of landmarks (a tilt a moves every spot like a translation of
            about (ceiling - camera height) a), so a tilted fit is far noisier than a level
            one: with 0.3 px noise and 3-4 landmarks within ~1 m at 2.5 m, several cm against
            ~2 mm. Hence the test, and the recommendation to catch floor bumps primarily with
            the filter's innovation gate.
        pixel_sigma_px: standard deviation of a spot centre per axis, pixels: one for all,
            or one per landmark (e.g. growing with the radius, `noise_model`).
        loss: robust loss of the level fit, "huber" or "cauchy" (`pose_planar`), or None
            (least squares); `loss_scale` is its threshold in sigmas.
        landmark_ids: IDs to carry into the fix.
        tilt_sigma_rad: optional zero-mean prior on roll and pitch (None: no prior).
        floor_prior: a prior on the body's tilt and height above the map's floor,
            ((roll, pitch radians, dz metres), covariance (3, 3)): the floor carried from
            earlier fixes (`floor_plane`). Given, the level fit is solved on that floor (at
            the prior's tilt and height), and the test below is made around it: with 3+
            landmarks and `estimate_tilt` the tilted fit (tilt and height too, the prior's
            Bayesian update, robust by the carried fit's weights) is taken when it lowers
            the chi-square by more than `tilt_min_chi2_drop`; then `floor` and
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
        tilt_min_chi2_drop: the tilted fit is taken only when it lowers the chi-square
            (sum of squared reprojection errors over sigma^2) by more than this; 9.21 is the
            99 % point of chi-square with 2 dof, 0 always takes it.
        min_separation_px: spots closer than this in the image count as coincident.
        max_iterations: Gauss-Newton iterations before giving up.

    Returns:
        The fix, or None when degenerate: fewer than 2 landmarks, coincident landmarks, a
        landmark not above the camera, a singular problem or no convergence.

    Raises:
        ValueError: when `pixels` and `p_world` have mismatched or wrong shapes.
    """
    rays = _rays_on_landmark_planes(camera, pixels, p_world, min_separation_px, floor_prior)
    if rays is None:
        return None
    fit = _level_fit(rays, initial, pixel_sigma_px, loss, loss_scale, max_iterations)
    if fit is None:
        return None
    # Tilt only when the data demand it: the level fit's chi-square must drop by more than
    # `tilt_min_chi2_drop` (a likelihood-ratio test, 2 dof). The drop cannot exceed the level
    # fit's own chi-square, so a consistent level fit skips the tilted solve altogether.
    test = estimate_tilt and rays.n >= 3 and fit.chi2 > tilt_min_chi2_drop
    if floor_prior is not None:
        fit = _on_carried_floor(
            rays, fit, floor_prior, test, loss, loss_scale, tilt_min_chi2_drop,
            calibration_jacobian, floor_sensitivity, max_iterations,
        )  # fmt: skip
    elif test:
        tilt0 = initial.tilt if isinstance(initial, PoseFix) else (0.0, 0.0)
        fit = _zero_mean_tilt(rays, fit, tilt0, tilt_sigma_rad, tilt_min_chi2_drop, max_iterations)
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


# ---------------------------------------------------------------------------------------------
# solve_pose's steps: the rays, the level fit, the tilt test (on the carried floor or zero-mean)


@dataclass(frozen=True, slots=True)
class _Rays:
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


@dataclass(slots=True)
class _Fit:
    """A fit on its way to a `PoseFix`: the pose, its covariance and what the tests need
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


def _rays_on_landmark_planes(
    camera: CameraModel,
    pixels: npt.ArrayLike,
    p_world: npt.ArrayLike,
    min_separation_px: float,
    floor_prior: tuple[tuple[float, float, float], FloatArray] | None,
) -> _Rays | None:
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
    return _Rays(pl, Pl, m, A, q, G, P_xy, heights, camera.T_body_camera)


def _level_fit(
    rays: _Rays,
    initial: PoseFix | tuple[float, float, float] | None,
    pixel_sigma_px: float | Sequence[float],
    loss: str | None,
    loss_scale: float,
    max_iterations: int,
) -> _Fit | None:
    """Step 2: the level (or carried-floor) planar fit from the closed form or `initial`."""
    q, G, P_xy = rays.q, rays.G, rays.P_xy
    if initial is None:
        weights = [
            1.0 / (g00 * g00 + g01 * g01 + g10 * g10 + g11 * g11) for g00, g01, g10, g11 in G
        ]
        start = procrustes_2d(q, P_xy, weights)
        if start is None:
            return None
    elif isinstance(initial, PoseFix):
        start = (initial.x, initial.y, initial.theta)
    else:
        start = (float(initial[0]), float(initial[1]), float(initial[2]))
    planar = solve_planar(
        q, G, P_xy, start, pixel_sigma_px, max_iterations, loss=loss, loss_scale=loss_scale
    )
    if planar is None:
        return None
    (x, y, theta), c, rms, res = planar
    n = rays.n
    sig = [pixel_sigma_px] * n if isinstance(pixel_sigma_px, int | float) else pixel_sigma_px
    chi2 = sum([(r / si) ** 2 for r, si in zip(res, sig, strict=True)])
    covariance = np.array([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]])
    return _Fit(x, y, theta, covariance, rms, tuple(res), chi2, list(sig), list(res), np.zeros(2))


def _on_carried_floor(
    rays: _Rays,
    fit: _Fit,
    floor_prior: tuple[tuple[float, float, float], FloatArray],
    test: bool,
    loss: str | None,
    loss_scale: float,
    tilt_min_chi2_drop: float,
    calibration_jacobian: Callable[[list[list[float]]], FloatArray] | None,
    floor_sensitivity: FloatArray | None,
    max_iterations: int,
) -> _Fit:
    """Step 3 with a carried floor: its fit (step 2's) unless the spots demand a floor of
    their own: the tilted fit with the carried floor as its prior must lower the chi-square
    by more than `tilt_min_chi2_drop` (the likelihood-ratio test of the zero-mean case,
    around the carried floor instead of the level one), and, given the calibration's
    Jacobian, its floor's change must be significant against the calibration's error too."""
    e0, _ = floor_prior
    fit.floor = np.array(e0, dtype=np.float64)
    fit.tilt = fit.floor[:2].copy()
    if not test:
        return fit
    sig, res = fit.sigmas, fit.raw_residuals
    # the carried fit's robust weights kept: sigma_i / sqrt(w_i)
    w = [ROBUST_WEIGHTS[loss](r / si, loss_scale) if loss else 1.0
         for r, si in zip(res, sig, strict=True)]  # fmt: skip
    sig_w = [si / math.sqrt(wi) for si, wi in zip(sig, w, strict=True)]
    tilted = solve_tilted(rays.m, rays.A, rays.heights, rays.P_xy, rays.T_body_camera,
                          (fit.x, fit.y, fit.theta, *e0), sig_w, None, max_iterations,
                          floor_prior=floor_prior)  # fmt: skip
    if tilted is None:
        return fit
    params, cov_full, rms_t, res_t = tilted
    chi2_t = sum((r / si) ** 2 for r, si in zip(res_t, sig, strict=True))
    take = tilt_min_chi2_drop <= 0 or fit.chi2 - chi2_t > tilt_min_chi2_drop
    if take and calibration_jacobian is not None:
        change, fit.floor_sensitivity = floor_change_chi2(
            rays.m, rays.A, rays.heights, rays.P_xy, rays.T_body_camera, params, cov_full,
            sig_w, floor_prior, calibration_jacobian(rays.pl), floor_sensitivity,
        )  # fmt: skip
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


def _zero_mean_tilt(
    rays: _Rays,
    fit: _Fit,
    tilt0: Sequence[float] | FloatArray,
    tilt_sigma_rad: float | None,
    tilt_min_chi2_drop: float,
    max_iterations: int,
) -> _Fit:
    """Step 3 without a carried floor: the tilted fit (roll, pitch; an optional zero-mean
    prior) taken when it lowers the level fit's chi-square by more than
    `tilt_min_chi2_drop`."""
    n = rays.n
    sigma_px = math.sqrt(sum([si * si for si in fit.sigmas]) / n)
    roll0, pitch0 = (float(v) for v in tilt0)
    tilted = solve_tilted(
        rays.m, rays.A, rays.heights, rays.P_xy, rays.T_body_camera,
        (fit.x, fit.y, fit.theta, roll0, pitch0), sigma_px, tilt_sigma_rad, max_iterations,
    )  # fmt: skip
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
