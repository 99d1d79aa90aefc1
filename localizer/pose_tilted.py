"""The pose solver with a tilted body: the problem in the level, heading-aligned frame.

A tilted body (roll, pitch; R_world_body = Rz(theta) Ry(pitch) Rx(roll)) is the level
problem of `pose_planar` in the level, heading-aligned frame with the mounting tilted:
T_level_camera = R_tilt T_body_camera (`level_mounting`). `solve_tilted` runs Gauss-Newton
over (x, y, theta, roll, pitch[, dz]) on that, with the derivatives in roll, pitch and dz by
forward differences of `pose_planar.floor_points`; `floor_change_chi2` tells whether a tilted
fit's floor differs from its prior's beyond what pixel noise and the calibration's error
make of it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from localizer.pose_planar import Mat2, Point, floor_points
from localizer.types import FloatArray


def rotation_world_body(theta: float, roll: float = 0.0, pitch: float = 0.0) -> FloatArray:
    """R_world_body = Rz(theta) Ry(pitch) Rx(roll), shape (3, 3)."""
    cz, sz = math.cos(theta), math.sin(theta)
    cy, sy = math.cos(pitch), math.sin(pitch)
    cx, sx = math.cos(roll), math.sin(roll)
    return np.array(
        [
            [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
            [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
            [-sy, cy * sx, cy * cx],
        ]
    )


def level_mounting(
    T_body_camera: FloatArray, roll: float, pitch: float, dz: float = 0.0
) -> list[list[float]]:
    """Rows 0-2 of T_level_camera = R_tilt T_body_camera + (0, 0, dz), R_tilt = Ry(pitch)
    Rx(roll) (the body's tilt moved into the mounting, and the body raised by dz: a floor
    above the map's); Python floats, as `floor_points` takes them."""
    cy, sy = math.cos(pitch), math.sin(pitch)
    cx, sx = math.cos(roll), math.sin(roll)
    R = ((cy, sy * sx, sy * cx), (0.0, cx, -sx), (-sy, cy * sx, cy * cx))
    T = T_body_camera[:3].tolist()
    rows = [[r0 * T[0][k] + r1 * T[1][k] + r2 * T[2][k] for k in range(4)] for r0, r1, r2 in R]
    rows[2][3] += dz
    return rows


def _tilted_residuals(
    m: list[Point],
    A: list[Mat2],
    z: list[float],
    P: list[Point],
    T_body_camera: FloatArray,
    params: list[float],
    sigma_px: Sequence[float],
    jacobian: bool,
    base: tuple[list[Point], list[Mat2]] | None = None,
) -> tuple[FloatArray, FloatArray | None, tuple[list[Point], list[Mat2]]] | None:
    """Whitened residuals e (2N,) and, when asked, their Jacobian J (2N, K) at `params`
    (x, y, theta, roll, pitch[, dz]) (K = 5 or 6; `sigma_px`: each landmark's pixel sigma).
    The derivatives in roll, pitch and dz are forward differences of `floor_points`.

    Also returns the `floor_points` at `params` (pass them back as `base` to reuse them).
    """
    h = 1e-6  # radians (metres for dz), forward-difference step
    x, y, th = params[:3]
    extra = list(params[3:]) + [0.0] * (6 - len(params))  # roll, pitch, dz
    if base is None:
        base = floor_points(m, A, z, level_mounting(T_body_camera, *extra))
        if base is None:
            return None
    q, G = base
    shifted: list[list[Point]] = []
    if jacobian:
        for k in range(len(params) - 3):
            moved = list(extra)
            moved[k] += h
            at = floor_points(m, A, z, level_mounting(T_body_camera, *moved))
            if at is None:
                return None
            shifted.append(at[0])
    n = len(q)
    c, s = math.cos(th), math.sin(th)
    e = np.empty(2 * n)
    J = np.empty((2 * n, len(params))) if jacobian else None
    for i, ((qx, qy), (g00, g01, g10, g11), (X, Y), si) in enumerate(
        zip(q, G, P, sigma_px, strict=True)
    ):
        det = (g00 * g11 - g01 * g10) * si
        if det == 0.0:
            return None
        w00, w01, w10, w11 = g11 / det, -g01 / det, -g10 / det, g00 / det
        dX, dY = X - x, Y - y
        u, v = c * dX + s * dY, -s * dX + c * dY
        rx, ry = qx - u, qy - v
        e[2 * i], e[2 * i + 1] = w00 * rx + w01 * ry, w10 * rx + w11 * ry
        if J is not None:
            # d(residual)/d(x, y, theta, roll, pitch[, dz]) per axis, then whitened
            jx = [c, s, -v] + [(qk[i][0] - qx) / h for qk in shifted]
            jy = [-s, c, u] + [(qk[i][1] - qy) / h for qk in shifted]
            J[2 * i] = [w00 * a + w01 * b for a, b in zip(jx, jy, strict=True)]
            J[2 * i + 1] = [w10 * a + w11 * b for a, b in zip(jx, jy, strict=True)]
    return e, J, base


def solve_tilted(
    m: list[Point],
    A: list[Mat2],
    z: list[float],
    P: list[Point],
    T_body_camera: FloatArray,
    start: tuple[float, ...],
    sigma_px: float | Sequence[float],
    tilt_sigma_rad: float | None,
    max_iterations: int,
    *,
    floor_prior: tuple[tuple[float, float, float], FloatArray] | None = None,
) -> tuple[list[float], FloatArray, float, list[float]] | None:
    """Gauss-Newton over (x, y, theta, roll, pitch[, dz]) on the whitened floor-plane
    residuals.

    Minimises sum_i |e_i|^2 + (t - t0)^T Pt^-1 (t - t0) over the pose and the extras t: the
    reprojection errors over each landmark's sigma plus a Gaussian prior on t. With
    `floor_prior` (t0, Pt), t = (roll, pitch, dz), the body's tilt and its height above the
    map's floor (e.g. the floor carried from earlier frames, `floor_plane`): the result is
    the Bayesian update of that prior, the extras' block of the returned covariance its
    posterior. Without, t = (roll, pitch) (dz = 0), with the zero-mean prior
    `tilt_sigma_rad` (None: no prior).

    Tilt and translation are nearly interchangeable (a tilt by a shifts every spot like a
    translation by about (ceiling - camera height) a), so the problem is ill-conditioned and a
    plain Gauss-Newton step overshoots along that direction; each step is therefore scaled by
    the minimum of the parabola through the cost at 0 (value and slope) and at the full step.

    Args:
        m, A, z: as `floor_points`; P: the landmarks' world (x, y).
        T_body_camera: the mounting, shape (4, 4).
        start: initial (x, y, theta, roll, pitch[, dz]) (dz only with `floor_prior`).
        sigma_px: pixel noise, one for all or one per landmark.
        tilt_sigma_rad, floor_prior: the prior (above; `floor_prior` wins).

    Returns:
        (params, covariance shape (K, K), residual RMS in pixels, each landmark's
        reprojection error in pixels), or None when a landmark is not above the camera, the
        problem is singular or it does not converge.
    """
    n = len(m)
    sig = [float(sigma_px)] * n if isinstance(sigma_px, int | float) else list(sigma_px)
    t0 = np.zeros(2)
    W = np.zeros((2, 2))  # the prior's information matrix
    params = list(start[:5])
    if floor_prior is not None:
        t0 = np.asarray(floor_prior[0], dtype=np.float64)
        W = np.linalg.inv(np.asarray(floor_prior[1], dtype=np.float64))
        params = [*start[:5], float(start[5]) if len(start) > 5 else float(t0[2])]
    elif tilt_sigma_rad is not None:
        W = np.eye(2) / tilt_sigma_rad**2
    nk = len(params)

    def cost(e: FloatArray, p: list[float]) -> float:
        d = np.array(p[3:]) - t0
        return float(e @ e + d @ W @ d)

    base = None  # floor points at params, when already known
    for _ in range(max_iterations):
        res = _tilted_residuals(m, A, z, P, T_body_camera, params, sig, True, base)
        if res is None:
            return None
        e, J, _ = res
        if J is None:
            return None
        H = J.T @ J
        g = J.T @ e
        H[3:nk, 3:nk] += W
        g[3:nk] += W @ (np.array(params[3:]) - t0)
        try:
            cov: FloatArray = np.linalg.inv(H).astype(np.float64)
        except np.linalg.LinAlgError:
            return None
        delta = -(cov @ g)
        step2 = -float(delta @ g)  # = delta^T H delta: the step in standard deviations^2
        if step2 < 1e-6:
            break
        trial = [p + d for p, d in zip(params, delta.tolist(), strict=True)]
        at_trial = _tilted_residuals(m, A, z, P, T_body_camera, trial, sig, False)
        if at_trial is None:
            return None
        # cost(a) ~ c0 - 2 s a + k a^2 through c0, slope -2 s and cost(1): minimum at s / k
        c0, c1 = cost(e, params), cost(at_trial[0], trial)
        k = c1 - c0 + 2.0 * step2
        alpha = 1.0 if k <= step2 else max(step2 / k, 0.1)
        if alpha == 1.0:
            params, base, e = trial, at_trial[2], at_trial[0]
        else:
            params, base = (
                [p + alpha * d for p, d in zip(params, delta.tolist(), strict=True)],
                None,
            )
            at = _tilted_residuals(m, A, z, P, T_body_camera, params, sig, False)
            if at is None:
                return None
            e = at[0]
        if step2 * alpha * alpha < 1e-4:  # the step is under 1 % of a standard deviation
            break
    else:
        return None
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) <= 0):
        return None
    res_px = [si * math.hypot(float(e[2 * i]), float(e[2 * i + 1])) for i, si in enumerate(sig)]
    rms = math.sqrt(sum(r * r for r in res_px) / n)
    return params, cov, rms, res_px


def floor_change_chi2(
    m: list[Point],
    A: list[Mat2],
    z: list[float],
    P: list[Point],
    T_body_camera: FloatArray,
    params: list[float],
    covariance: FloatArray,
    sigma_px: Sequence[float],
    floor_prior: tuple[tuple[float, float, float], FloatArray],
    calibration_jacobian: FloatArray,
    prior_sensitivity: FloatArray | None = None,
) -> tuple[float, FloatArray | None]:
    """How far a tilted fit's floor is from its prior's mean, in the spread that pixel noise
    and the calibration's error give it when the floor is the prior's (a Wald statistic).

    The tilted fit (`solve_tilted` with `floor_prior` (e0, Pw), result `params` and
    `covariance` C, K = 6) moves the floor by d = e - e0. Linearised, a pixel error n
    (whitened) and a calibration error dc move the estimate by C J^T (n + J_c dc), J the
    whitened residuals' Jacobian, J_c = d pixel / d c over each spot's sigma, dc of covariance
    identity (`calibration_jacobian` scaled by the calibration's standard deviations). The
    prior's mean e0 may itself hold the calibration's error, K0 dc (`prior_sensitivity` K0,
    the carried floor's, learnt from earlier frames through the same lens: a Schmidt consider
    state); the fit's floor then holds E dc, and with the prior Pi = blockdiag(0, Pw^-1) on
    the extras,

        E = (C J^T J_c)_e + C_ee Pw^-1 K0,    D = E - K0,
        S = (C - C Pi C)_ee + D D^T,          chi2 = d^T S^-1 d:

    chi-square with 3 dof when the floor is the prior's. The calibration's part D does not
    shrink with the number of landmarks (`calibration_consider`), which is why a dense grid's
    structured residuals do not by themselves make it large; it is small where the carried
    floor was learnt from a like view (the same error in both: a slope followed along a
    ramp), the whole of E where the prior knows nothing of the lens (K0 = 0) or the body has
    turned since (the lens's pseudo-tilt turns with the body, a floor's does not).

    Args:
        m, A, z, P, T_body_camera: as `solve_tilted`.
        params: the tilted fit's (x, y, theta, roll, pitch, dz).
        covariance: its covariance, shape (6, 6).
        sigma_px: each landmark's sigma of that fit, pixels.
        floor_prior: the fit's prior (e0, Pw) on (roll, pitch, dz).
        calibration_jacobian: d pixel / d c times the calibration's standard deviations,
            shape (N, 2, Q).
        prior_sensitivity: K0, shape (3, Q), or None (zero).

    Returns:
        (chi2, E shape (3, Q)): chi2 inf when the floor's spread is singular; (nan, None)
        when a landmark is not above the camera.
    """
    at = _tilted_residuals(m, A, z, P, T_body_camera, list(params), sigma_px, True)
    if at is None or at[1] is None:
        return math.nan, None
    J = at[1]
    sig = np.repeat(np.asarray(sigma_px, dtype=np.float64), 2)
    Jc = np.asarray(calibration_jacobian, dtype=np.float64).reshape(len(sig), -1) / sig[:, None]
    C = np.asarray(covariance, dtype=np.float64)
    W_inv = np.linalg.inv(np.asarray(floor_prior[1], dtype=np.float64))
    Pi = np.zeros((6, 6))
    Pi[3:, 3:] = W_inv
    E = (C @ (J.T @ Jc))[3:]
    D = E
    if prior_sensitivity is not None and prior_sensitivity.shape == E.shape:
        E = E + C[3:, 3:] @ W_inv @ prior_sensitivity
        D = E - prior_sensitivity
    S = (C - C @ Pi @ C)[3:, 3:] + D @ D.T
    d = np.asarray(params[3:6], dtype=np.float64) - np.asarray(floor_prior[0], dtype=np.float64)
    try:
        return float(d @ np.linalg.solve(0.5 * (S + S.T), d)), E
    except np.linalg.LinAlgError:
        return math.inf, E
