"""Online self-calibration: the principal point, the first distortion term and the mounting
yaw, estimated from the stream of fixes where the data make them observable.

A window of frames, each with its matched spots (pixels), their landmarks (world points) and
the raw odometry pose at the frame, is adjusted jointly (a small bundle adjustment,
`scipy.optimize.least_squares` with a sparse Jacobian): the unknowns are the corrections
c = (delta cu, delta cv, relative change of the first distortion coefficient, mounting yaw)
and every frame's pose; the residuals are the reprojection errors over the pixel sigma, the
odometry's relative motion between consecutive frames over its sigma, and a weak prior on c.

What makes each correction observable (and so when it converges, see `converged`):
- the first distortion term: landmarks over a range of image radii in the same frame (many
  landmarks in view; a 3-landmark cluster at one radius leaves it to the prior);
- the principal point: a shift of it moves every spot almost alike, like a translation of
  the body; what tells them apart is the distortion pattern around the true centre (a
  strong wide lens shows it in one view) and turning in place (the translation it mimics
  turns with the heading while odometry says the body stayed);
- the mounting yaw: a yawed camera turns every fix's heading alike, invisible in one frame;
  driving straight, odometry says which way the body moved, and the fixes' track shows the
  yaw between the two.

The prior's standard deviations are the calibration's own uncertainty. `converged` holds,
per correction, whether its posterior standard deviation fell below `converge_*` (a
fraction of the prior): only those are applied (`apply_to`).
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from localizer.camera import CameraModel, predict_pixels
from localizer.geometry import T_world_body_from_pose, wrap_angle

FloatArray = npt.NDArray[np.float64]
Pose = tuple[float, float, float]
NAMES = ("cu_px", "cv_px", "k1_rel", "yaw_rad")


@dataclass(frozen=True)
class SelfCalibrationConfig:
    """Tuning of `SelfCalibration`.

    Attributes:
        window_frames: frames adjusted together (the latest).
        min_landmarks: frames with fewer matched landmarks are not kept.
        pixel_sigma_px: reprojection noise, pixels.
        odometry_sigma_m: noise of odometry's relative translation between two kept
            frames, metres (plus `odometry_sigma_frac` of the distance forward and
            `odometry_lateral_frac` of it sideways: wheels slip little sideways).
        odometry_sigma_frac: relative part of it, forward (wheel scale).
        odometry_lateral_frac: relative part of it, sideways.
        odometry_sigma_rad: noise of its relative rotation, radians.
        prior_sigma: prior standard deviations of (cu px, cv px, k1 relative, yaw rad).
        converge_fraction: a correction has converged when its posterior standard
            deviation is below this fraction of its prior's.
    """

    window_frames: int = 40
    min_landmarks: int = 3
    pixel_sigma_px: float = 0.5
    odometry_sigma_m: float = 0.0005
    odometry_sigma_frac: float = 0.01
    odometry_lateral_frac: float = 0.002
    odometry_sigma_rad: float = 0.002
    prior_sigma: tuple[float, float, float, float] = (1.0, 1.0, 0.1, 0.02)
    converge_fraction: float = 0.25


@dataclass(frozen=True, eq=False)
class CalibrationEstimate:
    """The corrections (`NAMES` order), their covariance, and which have converged."""

    correction: FloatArray
    covariance: FloatArray
    converged: tuple[bool, bool, bool, bool]
    frames: int

    @property
    def sigma(self) -> FloatArray:
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))


def corrected_camera(camera: CameraModel, c: npt.ArrayLike) -> CameraModel:
    """`camera` with the corrections c = (dcu, dcv, k1 relative, yaw) applied."""
    dcu, dcv, dk1, yaw = (float(v) for v in np.asarray(c, dtype=np.float64))
    d = camera.distortion.copy()
    d[0] = d[0] * (1.0 + dk1) if d[0] != 0 else dk1
    T = camera.T_body_camera.copy()
    cz, sz = math.cos(yaw), math.sin(yaw)
    T[:3, :3] = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]]) @ T[:3, :3]
    return dataclasses.replace(camera, cu=camera.cu + dcu, cv=camera.cv + dcv, distortion=d,
                               T_body_camera=T)  # fmt: skip


def _relative(a: Pose, b: Pose) -> tuple[float, float, float]:
    """b in a's frame: (forward, left, turn)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, float(wrap_angle(b[2] - a[2]))


class SelfCalibration:
    """Collects fixes and estimates the corrections (see the module docstring).

    Args:
        camera: the calibration handed over.
        config: tuning.
    """

    def __init__(self, camera: CameraModel, config: SelfCalibrationConfig | None = None):
        self.camera = camera
        self.config = config or SelfCalibrationConfig()
        self._frames: deque[tuple[FloatArray, FloatArray, Pose, Pose]] = deque(
            maxlen=self.config.window_frames
        )
        self.estimate: CalibrationEstimate | None = None

    def __len__(self) -> int:
        return len(self._frames)

    def add(
        self, pixels: npt.ArrayLike, p_world: npt.ArrayLike, pose: Pose, odometry: Pose
    ) -> None:
        """One fix: the spots (N, 2), their landmarks (N, 3), the fixed pose and the raw
        odometry pose at that frame."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if len(px) < self.config.min_landmarks:
            return
        P = np.asarray(p_world, dtype=np.float64).reshape(-1, 3)
        self._frames.append((px, P, tuple(pose), tuple(odometry)))  # type: ignore[arg-type]

    def solve(self) -> CalibrationEstimate | None:
        """Adjust the window; None with fewer than two frames or when it fails."""
        frames = list(self._frames)
        M = len(frames)
        if M < 2:
            return None
        cfg = self.config
        prior = np.asarray(cfg.prior_sigma, dtype=np.float64)
        n_px = [len(f[0]) for f in frames]
        n_res = 2 * sum(n_px) + 3 * (M - 1) + 4
        x0 = np.concatenate([np.zeros(4), np.array([f[2] for f in frames]).ravel()])
        odo = [_relative(frames[i][3], frames[i + 1][3]) for i in range(M - 1)]

        def residuals(x: FloatArray) -> FloatArray:
            cam = corrected_camera(self.camera, x[:4])
            out = []
            for i, (px, P, _, _) in enumerate(frames):
                pose = x[4 + 3 * i : 7 + 3 * i]
                pred, ok = predict_pixels(cam, T_world_body_from_pose(*pose), P)
                r = np.where(ok[:, None], pred - px, 0.0) / cfg.pixel_sigma_px
                out.append(r.ravel())
            for i, (f, l, t) in enumerate(odo):
                a = x[4 + 3 * i : 7 + 3 * i]
                b = x[7 + 3 * i : 10 + 3 * i]
                rf, rl, rt = _relative((a[0], a[1], a[2]), (b[0], b[1], b[2]))
                d = math.hypot(f, l)
                s = cfg.odometry_sigma_m + cfg.odometry_sigma_frac * d
                s_lat = cfg.odometry_sigma_m + cfg.odometry_lateral_frac * d
                turn = float(wrap_angle(rt - t)) / cfg.odometry_sigma_rad
                out.append(np.array([(rf - f) / s, (rl - l) / s_lat, turn]))
            out.append(x[:4] / prior)
            return np.concatenate(out)

        sparsity = lil_matrix((n_res, 4 + 3 * M), dtype=np.int8)
        row = 0
        for i, n in enumerate(n_px):
            sparsity[row : row + 2 * n, :4] = 1
            sparsity[row : row + 2 * n, 4 + 3 * i : 7 + 3 * i] = 1
            row += 2 * n
        for i in range(M - 1):
            sparsity[row : row + 3, 4 + 3 * i : 10 + 3 * i] = 1
            row += 3
        for k in range(4):
            sparsity[row + k, k] = 1
        try:
            sol = least_squares(residuals, x0, jac_sparsity=sparsity, x_scale="jac",
                                method="trf", max_nfev=50)  # fmt: skip
        except (ValueError, np.linalg.LinAlgError):
            return None
        J = sol.jac.toarray() if hasattr(sol.jac, "toarray") else np.asarray(sol.jac)
        try:
            cov_full = np.linalg.inv(J.T @ J)
        except np.linalg.LinAlgError:
            return None
        cov = cov_full[:4, :4]
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        conv = tuple(bool(s < cfg.converge_fraction * p) for s, p in zip(sig, prior, strict=True))
        self.estimate = CalibrationEstimate(sol.x[:4].copy(), cov, conv, M)  # type: ignore[arg-type]
        return self.estimate

    def apply_to(self, camera: CameraModel) -> CameraModel:
        """`camera` with the converged corrections of the last `solve` applied."""
        est = self.estimate
        if est is None:
            return camera
        c = np.where(np.array(est.converged), est.correction, 0.0)
        return corrected_camera(camera, c)
