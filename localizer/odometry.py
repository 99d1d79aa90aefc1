"""Dead reckoning of a differential-drive robot from wheel speeds (paper Sec. IV-B).

`integrate_odometry` is the paper's eqs. (5)-(6) (a straight chord along the midpoint
heading); `integrate_arc` is the exact motion under constant wheel speeds over the step (a
circular arc, or a straight line when the wheels turn at the same speed). They differ by
O(dR^3) per step. `odometry_partials` gives the derivatives of eqs. (5)-(6) that the pose
filter's Jacobians are built from. The integrators accept scalars or equally shaped
arrays (vectorised).
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np

from localizer.geometry import wrap_angle
from localizer.types import FloatArray

Scalar = float | FloatArray


def odometry_increments(
    v_left: Scalar, v_right: Scalar, dt: Scalar, wheel_base: Scalar
) -> tuple[Scalar, Scalar]:
    """The translation and rotation over one step, eq. (6).

    Args:
        v_left, v_right: wheel ground speeds, m/s.
        dt: step, seconds.
        wheel_base: distance between the wheels W, metres.

    Returns:
        (dT metres, dR radians): dT = (v_l + v_r) / 2 dt, dR = (v_r - v_l) / W dt.
    """
    return 0.5 * (v_left + v_right) * dt, (v_right - v_left) / wheel_base * dt


@overload
def integrate_odometry(
    x: float,
    y: float,
    theta: float,
    v_left: float,
    v_right: float,
    dt: float,
    wheel_base: float,
) -> tuple[float, float, float]: ...
@overload
def integrate_odometry(
    x: Scalar,
    y: Scalar,
    theta: Scalar,
    v_left: Scalar,
    v_right: Scalar,
    dt: Scalar,
    wheel_base: Scalar,
) -> tuple[Scalar, Scalar, Scalar]: ...
def integrate_odometry(
    x: Scalar,
    y: Scalar,
    theta: Scalar,
    v_left: Scalar,
    v_right: Scalar,
    dt: Scalar,
    wheel_base: Scalar,
) -> tuple[Scalar, Scalar, Scalar]:
    """One dead-reckoning step, the paper's eqs. (5)-(6) (midpoint heading).

    x_t = x + dT cos(theta + dR/2), y_t = y + dT sin(theta + dR/2), theta_t = theta + dR.

    Args:
        x, y: position, metres; theta: REP-103 heading, radians.
        v_left, v_right: wheel speeds, m/s; dt: seconds; wheel_base: W, metres.

    Returns:
        (x, y, theta) after the step, theta wrapped to (-pi, pi]. Floats for float inputs,
        arrays of the broadcast shape otherwise.
    """
    dT, dR = odometry_increments(v_left, v_right, dt, wheel_base)
    heading = theta + 0.5 * dR
    if isinstance(heading, float):  # scalars: math is ~10x faster than numpy on floats
        th = wrap_angle(theta + dR)
        return x + dT * math.cos(heading), y + dT * math.sin(heading), th
    return x + dT * np.cos(heading), y + dT * np.sin(heading), wrap_angle(theta + dR)


@overload
def integrate_arc(
    x: float,
    y: float,
    theta: float,
    v_left: float,
    v_right: float,
    dt: float,
    wheel_base: float,
) -> tuple[float, float, float]: ...
@overload
def integrate_arc(
    x: Scalar,
    y: Scalar,
    theta: Scalar,
    v_left: Scalar,
    v_right: Scalar,
    dt: Scalar,
    wheel_base: Scalar,
) -> tuple[Scalar, Scalar, Scalar]: ...
def integrate_arc(
    x: Scalar,
    y: Scalar,
    theta: Scalar,
    v_left: Scalar,
    v_right: Scalar,
    dt: Scalar,
    wheel_base: Scalar,
) -> tuple[Scalar, Scalar, Scalar]:
    """One exact step under constant wheel speeds: a circular arc of turn dR and length dT.

    The chord of the arc has the midpoint heading of eq. (5) and the length
    dT sin(dR/2) / (dR/2), which tends to dT in the straight-line limit (dR -> 0).

    Args and returns: as `integrate_odometry`.
    """
    dT, dR = odometry_increments(v_left, v_right, dt, wheel_base)
    heading = theta + 0.5 * dR
    if isinstance(heading, float):  # scalars: math is ~10x faster than numpy on floats
        half = 0.5 * dR
        chord = dT * (math.sin(half) / half) if half != 0.0 else dT
        th = wrap_angle(theta + dR)
        return x + chord * math.cos(heading), y + chord * math.sin(heading), th
    chord = dT * np.sinc(dR / (2.0 * np.pi))  # np.sinc(u) = sin(pi u) / (pi u)
    return x + chord * np.cos(heading), y + chord * np.sin(heading), wrap_angle(theta + dR)


def odometry_partials(theta: float, dT: float, dR: float) -> tuple[float, float, float, float]:
    """Partial derivatives of eq. (5)'s position with respect to dT and dR (scalars).

    Returns:
        (dx/d dT, dy/d dT, dx/d dR, dy/d dR) = (c, s, -dT s / 2, dT c / 2) with c, s the
        cosine and sine of the midpoint heading theta + dR/2. With respect to theta the
        position moves twice as much as with respect to dR: d(x, y)/d theta = 2 d(x, y)/d dR.
    """
    heading = theta + 0.5 * dR
    c, s = math.cos(heading), math.sin(heading)
    return c, s, -0.5 * dT * s, 0.5 * dT * c
