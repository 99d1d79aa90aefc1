"""EKF fusing wheel odometry (eqs. 5-6) with landmark fixes, and learning the odometry's
systematic errors online (paper Sec. IV-B, taken past its hard switch).

State X = (x, y, theta, k_r, k_l, k_b): the body pose and three odometry calibration factors,
true right wheel speed = k_r v_r, true left = k_l v_l, true wheel base = k_b W (unequal wheel
radii and a wrong wheel base, the two dominant systematic errors of Borenstein's UMBmark). All
three are observable from fixes: driving straight shows (k_r - k_l) / k_b through the heading
drift and (k_r + k_l) / 2 through the distance, turning shows (k_r + k_l) / k_b.

Written line for line like the math (PythonRobotics style): `motion_model`, `jacob_f`,
`observation_model`, `jacob_h`, then the predict and update equations.

The output can be smoothed (`output_state`): a fix moves the estimate at once, but the
output follows it with a time constant, so the reported pose has no jumps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.geometry import wrap_angle
from localizer.odometry import integrate_odometry, odometry_jacobians
from localizer.pose import PoseFix

FloatArray = npt.NDArray[np.float64]

_H = np.hstack([np.eye(3), np.zeros((3, 3))])  # the fix observes (x, y, theta)


@dataclass(frozen=True)
class FilterConfig:
    """Noise model and tuning of `PoseFilter` (SI units).

    Attributes:
        wheel_noise_m_per_sqrt_s: white noise on each wheel's measured travel, metres per
            sqrt(second) (the speed noise's spectral density, (m/s)/sqrt(Hz)): over a step
            dt a wheel's travel has variance wheel_noise^2 dt, whatever the odometry rate.
        wheel_slip_m_per_sqrt_m: travel noise growing with distance (slip, uneven floor):
            variance wheel_slip^2 |travel| per wheel.
        calibration_walk_per_sqrt_s: random walk of each calibration factor, 1/sqrt(s)
            (lets the estimate follow slow changes: load, tyre wear).
        calibration_prior_sigma: prior standard deviation of each factor around 1.
        estimate_calibration: learn (k_r, k_l, k_b) from the fixes; False freezes them at
            their current value (1 at start).
        calibration_bounds: the factors are kept inside these bounds.
        output_time_constant_s: how fast `output_state` follows a correction, seconds
            (0: no smoothing).
        output_snap_m: a correction larger than this (a relocalisation) is not smoothed.
    """

    wheel_noise_m_per_sqrt_s: float = 0.001
    wheel_slip_m_per_sqrt_m: float = 0.002
    calibration_walk_per_sqrt_s: float = 1e-5
    calibration_prior_sigma: float = 0.03
    estimate_calibration: bool = True
    calibration_bounds: tuple[float, float] = (0.8, 1.2)
    output_time_constant_s: float = 0.2
    output_snap_m: float = 0.5

    def __post_init__(self) -> None:
        for name in (
            "wheel_noise_m_per_sqrt_s",
            "wheel_slip_m_per_sqrt_m",
            "calibration_walk_per_sqrt_s",
            "output_time_constant_s",
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"FilterConfig: {name} must be >= 0, got {v!r}")
        for name in ("calibration_prior_sigma", "output_snap_m"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"FilterConfig: {name} must be > 0, got {v!r}")
        lo, hi = self.calibration_bounds
        if not 0 < lo < 1 < hi:
            raise ValueError(
                f"FilterConfig: calibration_bounds must satisfy 0 < lo < 1 < hi, got {(lo, hi)}"
            )


@dataclass(frozen=True)
class OdometryCalibration:
    """Estimated odometry factors: true = factor x nominal.

    Attributes:
        right_scale, left_scale: wheel speed factors k_r, k_l (wheel radius errors).
        wheel_base_scale: k_b, true wheel base over the configured one.
        covariance: of (k_r, k_l, k_b), shape (3, 3).
    """

    right_scale: float
    left_scale: float
    wheel_base_scale: float
    covariance: FloatArray


def motion_model(
    X: FloatArray, v_left: float, v_right: float, dt: float, wheel_base: float
) -> FloatArray:
    """X_t = f(X, u): eqs. (5)-(6) with the calibrated speeds k_l v_l, k_r v_r and base k_b W."""
    x, y, theta, k_r, k_l, k_b = X
    x, y, theta = integrate_odometry(x, y, theta, k_l * v_left, k_r * v_right, dt, k_b * wheel_base)
    return np.array([x, y, theta, k_r, k_l, k_b])


def jacob_f(
    X: FloatArray, v_left: float, v_right: float, dt: float, wheel_base: float
) -> tuple[FloatArray, FloatArray]:
    """(F = df/dX shape (6, 6), G = df/d(true wheel speeds) shape (6, 2))."""
    _, _, theta, k_r, k_l, k_b = X
    F_pose, F_wheels, F_base = odometry_jacobians(
        theta, k_l * v_left, k_r * v_right, dt, k_b * wheel_base
    )
    F = np.eye(6)
    F[:3, :3] = F_pose
    F[:3, 3] = F_wheels[:, 1] * v_right  # d / d k_r
    F[:3, 4] = F_wheels[:, 0] * v_left  # d / d k_l
    F[:3, 5] = F_base * wheel_base  # d / d k_b
    G = np.zeros((6, 2))
    G[:3] = F_wheels
    return F, G


def observation_model(X: FloatArray) -> FloatArray:
    """z = h(X) = (x, y, theta): a landmark fix observes the pose."""
    return X[:3].copy()


def jacob_h() -> FloatArray:
    """H = dh/dX, shape (3, 6)."""
    return _H


class PoseFilter:
    """Extended Kalman filter over (x, y, theta, k_r, k_l, k_b).

    Args:
        x, y, theta: initial pose, metres and radians.
        covariance: of the initial pose, shape (3, 3).
        wheel_base: the configured wheel base W, metres.
        config: noise model; defaults to `FilterConfig()`.
    """

    def __init__(
        self,
        x: float,
        y: float,
        theta: float,
        covariance: npt.ArrayLike,
        *,
        wheel_base: float,
        config: FilterConfig | None = None,
    ) -> None:
        if not math.isfinite(wheel_base) or wheel_base <= 0:
            raise ValueError(f"PoseFilter: wheel_base must be positive metres, got {wheel_base!r}")
        self.config = config or FilterConfig()
        self.wheel_base = float(wheel_base)
        self._X = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
        self._P = np.zeros((6, 6))
        if self.config.estimate_calibration:
            self._P[3:, 3:] = np.eye(3) * self.config.calibration_prior_sigma**2
        self._offset = np.zeros(3)  # output_state - state
        self.reset(x, y, theta, covariance)

    # -- state ----------------------------------------------------------------------------------
    @property
    def state(self) -> FloatArray:
        """The estimated pose (x, y, theta), shape (3,) (a copy)."""
        return self._X[:3].copy()

    @property
    def covariance(self) -> FloatArray:
        """Covariance of (x, y, theta), shape (3, 3) (a copy)."""
        return self._P[:3, :3].copy()

    @property
    def full_state(self) -> FloatArray:
        """(x, y, theta, k_r, k_l, k_b), shape (6,) (a copy)."""
        return self._X.copy()

    @property
    def full_covariance(self) -> FloatArray:
        """Covariance of `full_state`, shape (6, 6) (a copy)."""
        return self._P.copy()

    @property
    def output_state(self) -> FloatArray:
        """The smoothed pose for output, (x, y, theta) shape (3,): follows `state` without
        jumps (time constant `config.output_time_constant_s`)."""
        out = self._X[:3] + self._offset
        out[2] = wrap_angle(float(out[2]))
        return out

    @property
    def calibration(self) -> OdometryCalibration:
        """The estimated odometry factors."""
        k_r, k_l, k_b = (float(v) for v in self._X[3:])
        return OdometryCalibration(k_r, k_l, k_b, self._P[3:, 3:].copy())

    def reset(self, x: float, y: float, theta: float, covariance: npt.ArrayLike) -> None:
        """Restart from a pose; keeps the calibration learnt so far (and its covariance)."""
        cov = np.asarray(covariance, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise ValueError(f"PoseFilter.reset: covariance must be finite (3, 3), got {cov.shape}")
        if not all(math.isfinite(v) for v in (x, y, theta)):
            raise ValueError(f"PoseFilter.reset: non-finite pose {(x, y, theta)}")
        self._X[:3] = (x, y, wrap_angle(theta))
        self._P[:3, :] = 0.0
        self._P[:, :3] = 0.0
        self._P[:3, :3] = 0.5 * (cov + cov.T)
        self._offset[:] = 0.0

    # -- predict --------------------------------------------------------------------------------
    def predict(self, v_left: float, v_right: float, dt: float) -> None:
        """Dead-reckon over `dt` seconds with the measured wheel speeds (m/s); any rate."""
        if dt <= 0:
            return
        cfg = self.config
        X, P = self._X, self._P
        k_r, k_l = X[3], X[4]
        travel = np.abs([k_l * v_left * dt, k_r * v_right * dt])
        var_travel = cfg.wheel_noise_m_per_sqrt_s**2 * dt + cfg.wheel_slip_m_per_sqrt_m**2 * travel
        M = np.diag(var_travel / dt**2)  # covariance of the true wheel speeds, (m/s)^2

        F, G = jacob_f(X, v_left, v_right, dt, self.wheel_base)
        X = motion_model(X, v_left, v_right, dt, self.wheel_base)
        P = F @ P @ F.T + G @ M @ G.T
        if cfg.estimate_calibration:
            P[3:, 3:] += np.eye(3) * cfg.calibration_walk_per_sqrt_s**2 * dt

        self._X, self._P = X, 0.5 * (P + P.T)
        if cfg.output_time_constant_s > 0:
            self._offset *= math.exp(-dt / cfg.output_time_constant_s)
        else:
            self._offset[:] = 0.0

    # -- update ---------------------------------------------------------------------------------
    def innovation(self, fix: PoseFix) -> tuple[FloatArray, FloatArray]:
        """(y = z - h(X) with the heading wrapped, shape (3,); S = H P H^T + R, shape (3, 3))."""
        z = np.array([fix.x, fix.y, fix.theta])
        y = z - observation_model(self._X)
        y[2] = wrap_angle(float(y[2]))
        H = jacob_h()
        S = H @ self._P @ H.T + np.asarray(fix.covariance, dtype=np.float64)
        return y, S

    def nis(self, fix: PoseFix) -> float:
        """Normalised innovation squared y^T S^-1 y of a fix (chi-square, 3 dof), not applied."""
        y, S = self.innovation(fix)
        return float(y @ np.linalg.solve(S, y))

    def update_fix(self, fix: PoseFix, *, max_nis: float | None = None) -> float:
        """Fuse a landmark fix (measurement (x, y, theta) with `fix.covariance`).

        Args:
            fix: the fix.
            max_nis: when given, a fix whose NIS exceeds it is not applied (gate); e.g. the
                chi-square 3-dof 99.9 % quantile 16.27.

        Returns:
            The fix's NIS (normalised innovation squared) before the update.
        """
        y, S = self.innovation(fix)
        S_inv = np.linalg.inv(S)
        nis = float(y @ S_inv @ y)
        if max_nis is not None and not nis <= max_nis:
            return nis
        H = jacob_h()
        P = self._P
        K = P @ H.T @ S_inv
        X = self._X + K @ y
        I_KH = np.eye(6) - K @ H
        P = I_KH @ P @ I_KH.T + K @ np.asarray(fix.covariance) @ K.T  # Joseph form
        lo, hi = self.config.calibration_bounds
        X[3:] = np.clip(X[3:], lo, hi)

        jump = self._X[:3] - X[:3]
        jump[2] = wrap_angle(float(jump[2]))
        if math.hypot(jump[0], jump[1]) > self.config.output_snap_m:
            self._offset[:] = 0.0
        else:
            self._offset += jump
        X[2] = wrap_angle(float(X[2]))
        self._X, self._P = X, 0.5 * (P + P.T)
        return nis
