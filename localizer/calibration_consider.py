"""The calibration's share of a fix's covariance: a consider (Schmidt) term.

A calibration error is not noise of each spot: it distorts the whole image the same way, so
every landmark of a fix is displaced coherently and the pose error it causes does not shrink
with the number of landmarks. With the calibration parameters c (fu, fv, cu, cv and each
non-zero distortion coefficient) held fixed at their calibrated values but uncertain with
covariance Sigma_cal, the weighted least-squares fix over the landmarks' pixels has

    Sigma_fix = (J^T W J)^-1 + A Sigma_cal A^T,    A = (J^T W J)^-1 J^T W J_cal,

J = d pixel / d pose (x, y, theta) and J_cal = d pixel / d c, both stacked over the
landmarks (2N rows), W the fit's per-spot weights 1 / sigma_i^2. The first term shrinks like
1/N; the second does not (for a dense grid it is most of the fix's error, and it changes with
the view, so it is what makes fixes during a turn disagree). The localizer weighs with
`noise_model`'s per-spot sigmas, which also hold the calibration's per-spot part in
quadrature: that keeps the first term honest for two landmarks (where unmodelled spot errors
are what it covers) and costs little where the second dominates.

What can be, is cached per camera on a grid over the image and interpolated at each spot
(`CalibrationConsider`):

- d pixel / d s, s = b_xy / b_z the direction of the pixel's body-frame ray per metre of
  rise (a landmark at rise h above the camera sits at q = c_xy + h s in the body frame, so
  d pixel / d q = (d pixel / d s) / h);
- d pixel / d k for each distortion coefficient k at a fixed ray (finite differences of the
  projection, as `noise_model.calibration_sigma_table`). The intrinsics' part is exact:
  pixel = (fu x_d + cu, fv y_d + cv), so d pixel / d (fu, fv, cu, cv) at a fixed ray is
  ((u - cu) / fu, 0, 1, 0; 0, (v - cv) / fv, 0, 1).

Per fix: d q / d pose for q = Rz(theta)^T (P_xy - t) is [-Rz^T | (q_y, -q_x)], so each
landmark's J_i = (d pixel / d s)(px_i) [-Rz^T | (q_y, -q_x)] / h_i; then the three lines above.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, normalized_from_pixels, pixels_from_points_camera
from localizer.types import BoolArray, FloatArray

_GRID_STEP_PX = 20.0  # spacing of the cached tables over the image
_RAY_STEP = 1e-4  # central-difference step of s (per metre of rise)


def calibration_parameter_sigmas(
    camera: CameraModel, *, focal_rel: float, principal_px: float, distortion_rel: float
) -> FloatArray:
    """Standard deviations of (fu, fv, cu, cv, each non-zero distortion coefficient).

    fu and fv are taken as independent (Zhang's method estimates both), each `focal_rel` of
    itself; cu and cv `principal_px`; each non-zero coefficient `distortion_rel` of itself.

    Returns:
        shape (4 + K,), K the number of non-zero distortion coefficients; pixels and the
        coefficients' own units.
    """
    k = np.abs(camera.distortion[camera.distortion != 0.0])
    intrinsics = [camera.fu * focal_rel, camera.fv * focal_rel, principal_px, principal_px]
    return np.concatenate([intrinsics, k * distortion_rel])


def consider_covariance(
    J: FloatArray,
    weights: FloatArray,
    J_cal: FloatArray,
    Sigma_cal: FloatArray,
    noise_var: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """A weighted least-squares fix's covariance: its noise part and the calibration's.

    With C = (J^T W J)^-1 and A = C J^T W J_cal, the fix's error is C J^T W n + A dc for
    independent pixel noise n (variance `noise_var` per landmark and axis) and a calibration
    error dc (covariance Sigma_cal), hence

        Sigma_fix = C J^T W R W J C + A Sigma_cal A^T,    R = diag(noise_var);

    with W = R^-1 (weights the inverse noise variances) the first term is C itself.

    Args:
        J: d pixel / d state, shape (N, 2, S).
        weights: per-landmark weights of the fit, shape (N,).
        J_cal: d pixel / d calibration, shape (N, 2, P).
        Sigma_cal: the calibration's covariance, shape (P, P).
        noise_var: per-landmark independent pixel variance, shape (N,); None: 1 / weights.

    Returns:
        (noise part, A Sigma_cal A^T), both shape (S, S).

    Raises:
        numpy.linalg.LinAlgError: when J^T W J is singular.
    """
    Js = J.reshape(-1, J.shape[2])  # (2N, S)
    WJ = Js * np.repeat(weights, 2)[:, None]
    C: FloatArray = np.linalg.inv(WJ.T @ Js).astype(np.float64, copy=False)
    A = C @ (WJ.T @ J_cal.reshape(-1, J_cal.shape[2]))
    noise: FloatArray = C
    if noise_var is not None:
        WJC = WJ @ C
        noise = WJC.T @ (WJC * np.repeat(noise_var, 2)[:, None])
    return noise, A @ Sigma_cal @ A.T


def _bilinear(table: FloatArray, step: float, px: FloatArray) -> FloatArray:
    """`table` (rows, cols, a, b) sampled every `step` pixels from (0, 0), at pixels (N, 2):
    shape (N, a, b)."""
    rows, cols = table.shape[:2]
    flat = table.reshape(rows * cols, -1)
    fx = np.clip(px[:, 0] * (1.0 / step), 0.0, cols - 1.000001)
    fy = np.clip(px[:, 1] * (1.0 / step), 0.0, rows - 1.000001)
    j, i = fx.astype(np.intp), fy.astype(np.intp)
    a, b = (fx - j)[:, None], (fy - i)[:, None]
    k = i * cols + j
    out = (1 - b) * ((1 - a) * flat[k] + a * flat[k + 1]) + b * (
        (1 - a) * flat[k + cols] + a * flat[k + cols + 1]
    )
    shaped: FloatArray = out.reshape((len(px), *table.shape[2:]))
    return shaped


def _fill_invalid(table: FloatArray, ok: BoolArray) -> FloatArray:
    """Nodes past the invertible area take the value of the nearest valid node."""
    if ok.all() or not ok.any():
        return np.nan_to_num(table)
    from scipy.ndimage import distance_transform_edt

    _, (ii, jj) = distance_transform_edt(~ok, return_indices=True)
    out: FloatArray = table[ii, jj]
    return out


@dataclass(frozen=True, eq=False)
class CalibrationConsider:
    """The per-camera tables and the calibration's covariance (module docstring).

    Build with `CalibrationConsider.for_camera`.

    Attributes:
        camera: the calibrated camera.
        sigmas: the calibration parameters' standard deviations, shape (P,).
        table: on the grid, d pixel / d s (the first two columns) beside J_cal = d pixel / d
            (fu, fv, cu, cv, the non-zero distortion coefficients), shape (rows, cols, 2, 2 + P).
    """

    camera: CameraModel
    sigmas: FloatArray
    table: FloatArray

    @classmethod
    def for_camera(
        cls, camera: CameraModel, *, focal_rel: float, principal_px: float, distortion_rel: float
    ) -> CalibrationConsider:
        """Tabulate d pixel / d s and d pixel / d k over the image (every 20 px)."""
        sigmas = calibration_parameter_sigmas(
            camera, focal_rel=focal_rel, principal_px=principal_px, distortion_rel=distortion_rel
        )
        cols = math.ceil((camera.width - 1) / _GRID_STEP_PX) + 1
        rows = math.ceil((camera.height - 1) / _GRID_STEP_PX) + 1
        gx, gy = np.meshgrid(np.arange(cols) * _GRID_STEP_PX, np.arange(rows) * _GRID_STEP_PX)
        px = np.column_stack([gx.ravel(), gy.ravel()])
        m = normalized_from_pixels(camera, px)
        ok = np.all(np.isfinite(m), axis=1)
        rays = np.column_stack([np.where(ok[:, None], m, 0.0), np.ones(len(m))])
        # d pixel / d s: rays b = (s, 1) in the body frame, moved in s_x and s_y
        R = camera.T_body_camera[:3, :3]
        b = rays @ R.T
        ok &= b[:, 2] > 1e-6
        s = b[:, :2] / np.where(ok, b[:, 2], 1.0)[:, None]
        ds = np.zeros((len(px), 2, 2))  # d pixel / d s
        for axis in range(2):
            e = np.zeros(2)
            e[axis] = _RAY_STEP
            ones = np.ones(len(s))
            plus, _ = pixels_from_points_camera(camera, np.column_stack([s + e, ones]) @ R)
            minus, _ = pixels_from_points_camera(camera, np.column_stack([s - e, ones]) @ R)
            ds[:, :, axis] = (plus - minus) / (2 * _RAY_STEP)
        # J_cal: the intrinsics exactly, then d pixel / d k at the fixed camera ray by central
        # differences of one sigma
        nonzero = np.flatnonzero(camera.distortion != 0.0)
        J_cal = np.zeros((len(px), 2, 4 + len(nonzero)))
        J_cal[:, 0, 0] = (px[:, 0] - camera.cu) / camera.fu
        J_cal[:, 1, 1] = (px[:, 1] - camera.cv) / camera.fv
        J_cal[:, 0, 2] = J_cal[:, 1, 3] = 1.0
        for col, idx in enumerate(nonzero):
            h = float(sigmas[4 + col]) or 1e-6
            moved = []
            for sign in (1.0, -1.0):
                d = camera.distortion.copy()
                d[idx] += sign * h
                lens = dataclasses.replace(camera, distortion=d)
                moved.append(pixels_from_points_camera(lens, rays)[0])
            J_cal[:, :, 4 + col] = (moved[0] - moved[1]) / (2 * h)
        table = np.concatenate([ds, J_cal], axis=2)
        ok &= np.all(np.isfinite(table), axis=(1, 2))
        table = _fill_invalid(table.reshape(rows, cols, 2, -1), ok.reshape(rows, cols))
        table.setflags(write=False)
        return cls(camera=camera, sigmas=sigmas, table=table)

    def jacobians(
        self, pixels: FloatArray, p_world: FloatArray, pose: tuple[float, float, float]
    ) -> tuple[FloatArray, FloatArray]:
        """J = d pixel / d (x, y, theta), shape (N, 2, 3), and J_cal = d pixel / d c, shape
        (N, 2, P), at the spots' pixels (N, 2) of landmarks at p_world (N, 3) for a level
        body at `pose`."""
        x, y, theta = pose
        c, s = math.cos(theta), math.sin(theta)
        dx, dy = p_world[:, 0] - x, p_world[:, 1] - y
        q = np.column_stack([c * dx + s * dy, -s * dx + c * dy])  # Rz^T (P_xy - t)
        rise = p_world[:, 2] - self.camera.T_body_camera[2, 3]
        at = _bilinear(self.table, _GRID_STEP_PX, pixels)
        M = at[:, :, :2] / rise[:, None, None]  # d pixel / d q
        J_cal = at[:, :, 2:]
        # d q / d t = -Rz^T, d q / d theta = (q_y, -q_x)
        J_t = M @ np.array([[-c, -s], [s, -c]])
        J_theta = M @ np.column_stack([q[:, 1], -q[:, 0]])[:, :, None]
        J = np.concatenate([J_t, J_theta], axis=2)
        return J, J_cal

    def scaled_jacobian(self, pixels: npt.ArrayLike, calibration_scale: float = 1.0) -> FloatArray:
        """J_cal diag(sigmas) at the spots' pixels (N, 2): d pixel per standard deviation of
        each calibration parameter (its covariance then the identity), shape (N, 2, P);
        `calibration_scale` multiplies the standard deviations."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        J_cal = _bilinear(self.table, _GRID_STEP_PX, px)[:, :, 2:]
        scaled: FloatArray = J_cal * (calibration_scale * self.sigmas)
        return scaled

    def covariance(
        self,
        pixels: npt.ArrayLike,
        p_world: npt.ArrayLike,
        pose: tuple[float, float, float],
        sigma_px: npt.ArrayLike,
        calibration_scale: float = 1.0,
    ) -> tuple[FloatArray, FloatArray] | None:
        """A level fix's covariance in two parts (`consider_covariance`).

        Args:
            pixels: the spots, shape (N, 2), pixels.
            p_world: their landmarks, shape (N, 3), metres.
            pose: the fix (x, y, theta).
            sigma_px: the per-spot sigmas of the fit (its weights), shape (N,) or a scalar.
            calibration_scale: multiplies the calibration's standard deviations.

        Returns:
            ((J^T W J)^-1, A Sigma_cal A^T), each shape (3, 3) in (x, y, theta), SI units;
            None with fewer than two landmarks, a landmark not above the camera or a
            singular geometry.
        """
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        P = np.asarray(p_world, dtype=np.float64).reshape(-1, 3)
        if len(px) < 2 or np.any(P[:, 2] - self.camera.T_body_camera[2, 3] <= 1e-6):
            return None
        J, J_cal = self.jacobians(px, P, pose)
        sig = np.broadcast_to(np.asarray(sigma_px, dtype=np.float64), (len(px),))
        Sigma_cal = np.diag(np.square(calibration_scale * self.sigmas))
        try:
            return consider_covariance(J, 1.0 / np.square(sig), J_cal, Sigma_cal)
        except np.linalg.LinAlgError:
            return None
