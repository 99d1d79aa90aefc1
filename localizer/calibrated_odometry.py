"""The pose filter's models (paper eqs. 5-6), with the odometry's systematic errors in the state.

State X = (x, y, theta, k_r, k_l, k_b): the body pose and three odometry calibration factors,
true right wheel speed = k_r v_r, true left = k_l v_l, true wheel base = k_b W (unequal wheel
radii and a wrong wheel base, the two dominant systematic errors of Borenstein's UMBmark).

Written line for line like the math (PythonRobotics style): `motion_model` X_t = f(X, u),
its Jacobians `jacob_f`, and `observation_model` z = h(X) (H = [I 0]); `PoseFilter` runs the
predict and update equations on them. Plain floats and nested lists: odometry arrives at
50-200 Hz and for six states numpy's per-call cost dominates.
"""

from __future__ import annotations

from dataclasses import dataclass

from localizer.geometry import wrap_angle
from localizer.odometry import odometry_increments, odometry_partials
from localizer.types import FloatArray


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


State = list[float]  # (x, y, theta, k_r, k_l, k_b)
Rows = list[list[float]]


def motion_model(X: State, v_left: float, v_right: float, dt: float, wheel_base: float) -> State:
    """X_t = f(X, u): eqs. (5)-(6) with the calibrated speeds k_l v_l, k_r v_r and base k_b W."""
    return motion_step(X, v_left, v_right, dt, wheel_base)[0]


def jacob_f(
    X: State, v_left: float, v_right: float, dt: float, wheel_base: float
) -> tuple[Rows, Rows]:
    """The Jacobians of `motion_model`.

    Returns:
        (F_top: the pose rows of F = df/dX, 3 x 6 (the calibration rows of F are [0 I]; the
         pose block is [[1, 0, a], [0, 1, b], [0, 0, 1]] as eq. (5) gives),
         G: d(x, y, theta)_t / d(true wheel speeds k_l v_l, k_r v_r), 3 x 2).
    """
    _, F_top, G = motion_step(X, v_left, v_right, dt, wheel_base)
    return F_top, G


def motion_step(
    X: State, v_left: float, v_right: float, dt: float, wheel_base: float
) -> tuple[State, Rows, Rows]:
    """`motion_model` and `jacob_f` in one pass (they share the increments and the midpoint
    heading's sine and cosine): (X_t, F_top, G)."""
    x, y, theta, k_r, k_l, k_b = X
    W = k_b * wheel_base
    inc_T, inc_R = odometry_increments(k_l * v_left, k_r * v_right, dt, W)
    dT, dR = float(inc_T), float(inc_R)
    xT, yT, xR, yR = odometry_partials(theta, dT, dR)  # xT, yT: the midpoint heading's cos, sin
    X_t = [x + dT * xT, y + dT * yT, float(wrap_angle(theta + dR)), k_r, k_l, k_b]  # eq. (5)
    # chain rule through dT = (k_l v_l + k_r v_r) dt / 2 and dR = (k_r v_r - k_l v_l) dt / (k_b W)
    T_r, R_r = 0.5 * v_right * dt, v_right * dt / W  # d dT / d k_r, d dR / d k_r
    T_l, R_l = 0.5 * v_left * dt, -v_left * dt / W  # d dT / d k_l, d dR / d k_l
    R_b = -dR / k_b  # d dR / d k_b
    F_top = [
        [1.0, 0.0, 2.0 * xR, xT * T_r + xR * R_r, xT * T_l + xR * R_l, xR * R_b],
        [0.0, 1.0, 2.0 * yR, yT * T_r + yR * R_r, yT * T_l + yR * R_l, yR * R_b],
        [0.0, 0.0, 1.0, R_r, R_l, R_b],
    ]
    T_v, R_v = 0.5 * dt, dt / W  # d dT / d v (either wheel), d dR / d v_r (= -d dR / d v_l)
    G = [
        [xT * T_v - xR * R_v, xT * T_v + xR * R_v],
        [yT * T_v - yR * R_v, yT * T_v + yR * R_v],
        [-R_v, R_v],
    ]
    return X_t, F_top, G


def observation_model(X: State) -> list[float]:
    """z = h(X) = (x, y, theta): a landmark fix observes the pose, H = dh/dX = [I 0]."""
    return X[:3]
