"""The pose solver's fast path for a level body: the problem on the landmarks' height planes.

Without tilt, a landmark's ray from the optical centre c (body frame) meets the horizontal
plane at the landmark's own height z_i in one body-frame point

    q_i = c_xy + lambda_i b_i,xy,   b_i = R_body_camera (m_i, 1),   lambda_i = (z_i - c_z) / b_i,z,

which does not depend on the pose. The pose (x, y, theta) is then a 2D rigid registration of the
q_i onto the landmarks' world (x, y): q_i = Rz(theta)^T (P_i,xy - t). Each q_i's error is the
pixel noise mapped through G_i = d q_i / d pixel = (d q_i / d m_i) A_i, A_i = d m_i / d pixel,
so the whitened residual e_i = G_i^-1 (q_i - Rz^T (P_i - t)) / sigma is, to first order, the
reprojection error in pixels over sigma: the same least-squares problem as the reprojection
error in the image, solved on a few floats. Plain Python scalars on purpose: for 2-6 landmarks
they are several times faster than numpy's per-call overhead.

A tilted body (roll, pitch; R_world_body = Rz(theta) Ry(pitch) Rx(roll)) is the same problem
in the level, heading-aligned frame with the mounting tilted: T_level_camera = R_tilt
T_body_camera. `solve_tilted` runs Gauss-Newton over (x, y, theta, roll, pitch) on that,
with the derivatives in roll and pitch by forward differences of `floor_points`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from localizer.small_linalg import inverse_3x3_sym
from localizer.types import FloatArray

Point = tuple[float, float]
Mat2 = tuple[float, float, float, float]  # row-major a00 a01 a10 a11


def floor_points(
    m: list[Point],
    A: list[Mat2],
    z: list[float],
    T_body_camera: Sequence[Sequence[float]],
) -> tuple[list[Point], list[Mat2]] | None:
    """Body-frame points q_i on each landmark's height plane and their G_i = d q_i / d pixel.

    Args:
        m: undistorted normalised coordinates, N pairs.
        A: d m / d pixel per landmark, N row-major 2x2.
        z: landmark heights, metres, N.
        T_body_camera: the mounting, 4 x 4 nested lists.

    Returns:
        (q_i, G_i row-major), or None when a landmark is not above the camera.
    """
    (r00, r01, r02, cx), (r10, r11, r12, cy), (r20, r21, r22, cz) = T_body_camera[:3]
    qs: list[Point] = []
    Gs: list[Mat2] = []
    for (mx, my), (a00, a01, a10, a11), zi in zip(m, A, z, strict=True):
        bx = r00 * mx + r01 * my + r02
        by = r10 * mx + r11 * my + r12
        bz = r20 * mx + r21 * my + r22
        rise = zi - cz
        if bz <= 1e-9 or rise <= 1e-6:
            return None
        lam = rise / bz
        qs.append((cx + lam * bx, cy + lam * by))
        # d q / d m = lambda (R[:2, :2] - b_xy / b_z R[2, :2])
        ux, uy = bx / bz, by / bz
        d00, d01 = lam * (r00 - ux * r20), lam * (r01 - ux * r21)
        d10, d11 = lam * (r10 - uy * r20), lam * (r11 - uy * r21)
        Gs.append(
            (
                d00 * a00 + d01 * a10,
                d00 * a01 + d01 * a11,
                d10 * a00 + d11 * a10,
                d10 * a01 + d11 * a11,
            )
        )
    return qs, Gs


def procrustes_2d(
    q: list[Point], P: list[Point], w: list[float]
) -> tuple[float, float, float] | None:
    """Weighted rigid 2D transform (x, y, theta) with P_i ~ Rz(theta) q_i + (x, y).

    For two points this is the paper's eqs. (1)-(2) (scale known, = 1). Returns None when the
    points all coincide.
    """
    sw = sqx = sqy = sPx = sPy = sdot = scross = 0.0
    for wi, (a, b), (X, Y) in zip(w, q, P, strict=True):
        sw += wi
        sqx += wi * a
        sqy += wi * b
        sPx += wi * X
        sPy += wi * Y
        sdot += wi * (a * X + b * Y)
        scross += wi * (a * Y - b * X)
    qx, qy, Px, Py = sqx / sw, sqy / sw, sPx / sw, sPy / sw
    # centred sums: sum w (q - q0).(P - P0) = sum w q.P - sw q0.P0, likewise for the cross term
    dot = sdot - sw * (qx * Px + qy * Py)
    cross = scross - sw * (qx * Py - qy * Px)
    if math.hypot(dot, cross) < 1e-12:
        return None
    theta = math.atan2(cross, dot)
    c, s = math.cos(theta), math.sin(theta)
    return Px - (c * qx - s * qy), Py - (s * qx + c * qy), theta


def huber_weight(e: float, k: float) -> float:
    """IRLS weight of a whitened residual norm `e` under Huber's loss with threshold `k`
    (sigmas): 1 inside, k / e beyond (the loss grows linearly there, not quadratically)."""
    return 1.0 if e <= k else k / e


def cauchy_weight(e: float, k: float) -> float:
    """IRLS weight under the Cauchy (Lorentzian) loss with scale `k`: 1 / (1 + (e / k)^2)
    (a far outlier's influence goes to zero)."""
    return 1.0 / (1.0 + (e / k) ** 2)


ROBUST_WEIGHTS = {"huber": huber_weight, "cauchy": cauchy_weight}


def solve_planar(
    q: list[Point],
    G: list[Mat2],
    P: list[Point],
    start: tuple[float, float, float],
    sigma_px: float | Sequence[float],
    max_iterations: int,
    *,
    loss: str | None = None,
    loss_scale: float = 2.0,
) -> tuple[tuple[float, float, float], list[float], float, list[float]] | None:
    """Gauss-Newton for (x, y, theta) minimising sum rho(|G_i^-1 (q_i - Rz^T (P_i - t))| / sigma_i).

    With W_i = G_i^-1 / sigma_i, r_i = q_i - Rz^T (P_i - t) and (u_i, v_i) = Rz^T (P_i - t),
    the Jacobian of W_i r_i is W_i [Rz^T | (-v_i, u_i)], so J^T J and J^T e need only the
    information matrices O_i = W_i^T W_i: the (x, y) block is Rz (sum O_i) Rz^T, the rest
    comes from O_i r_i and O_i (-v_i, u_i) in the body frame. rho is the square (plain least
    squares) or, with `loss`, Huber's or Cauchy's loss by iteratively reweighted least
    squares: each round weighs O_i by `huber_weight` / `cauchy_weight` of landmark i's
    whitened residual and solves again, until the weights settle, so one bad spot pulls the
    pose by a bounded amount instead of quadratically. The least-squares fit is the first
    round; when every residual is within `loss_scale` it is already the answer (the usual
    frame pays nothing for the robust loss).

    Args:
        sigma_px: pixel standard deviation, one for all or one per landmark.
        loss: None, "huber" or "cauchy".
        loss_scale: the loss's threshold / scale, in sigmas.

    Returns:
        ((x, y, theta), covariance as (c00 c01 c02 c11 c12 c22), residual RMS in pixels,
        each landmark's reprojection error in pixels), or None when singular or not
        converged. The covariance is that of the weighted problem.
    """
    n = len(q)
    sig = [float(sigma_px)] * n if isinstance(sigma_px, int | float) else list(sigma_px)
    O0: list[tuple[float, float, float]] = []  # W^T W as (o00, o01, o11)
    for (g00, g01, g10, g11), si in zip(G, sig, strict=True):
        det = (g00 * g11 - g01 * g10) * si
        if det == 0.0:
            return None
        w00, w01, w10, w11 = g11 / det, -g01 / det, -g10 / det, g00 / det
        O0.append((w00 * w00 + w10 * w10, w00 * w01 + w10 * w11, w01 * w01 + w11 * w11))
    fit = _gauss_newton(q, P, O0, start, max_iterations)
    if fit is None:
        return None
    pose, cov = fit
    e = _whitened_norms(q, P, O0, pose)
    if loss is not None and max(e) > loss_scale:
        # Reweigh until the weights settle (plain least squares is the first iterate).
        weight = ROBUST_WEIGHTS[loss]
        ws = [1.0] * n
        for _ in range(max_iterations):
            new = [weight(v, loss_scale) for v in e]
            O = [(w * a, w * b, w * d) for w, (a, b, d) in zip(new, O0, strict=True)]
            fit = _gauss_newton(q, P, O, pose, max_iterations)
            if fit is None:
                return None
            pose, cov = fit
            e = _whitened_norms(q, P, O0, pose)
            if max(abs(u - v) for u, v in zip(new, ws, strict=True)) < 1e-3:
                break
            ws = new
    res = [si * v for si, v in zip(sig, e, strict=True)]
    rms = math.sqrt(sum([r * r for r in res]) / n)
    return pose, cov, rms, res


def _whitened_norms(
    q: list[Point],
    P: list[Point],
    O: list[tuple[float, float, float]],
    pose: tuple[float, float, float],
) -> list[float]:
    """|W_i r_i| per landmark at `pose`: the reprojection error in sigmas."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    out = []
    for (qx, qy), (X, Y), (o00, o01, o11) in zip(q, P, O, strict=True):
        dX, dY = X - x, Y - y
        rx, ry = qx - (c * dX + s * dY), qy - (-s * dX + c * dY)
        out.append(math.sqrt(max(o00 * rx * rx + 2.0 * o01 * rx * ry + o11 * ry * ry, 0.0)))
    return out


def _gauss_newton(
    q: list[Point],
    P: list[Point],
    O: list[tuple[float, float, float]],
    start: tuple[float, float, float],
    max_iterations: int,
) -> tuple[tuple[float, float, float], list[float]] | None:
    """Gauss-Newton on the whitened problem with information matrices O: (pose, H^-1)."""
    S00 = S01 = S11 = 0.0  # sum O_i (a loop: cheaper than three generator sums)
    for o00, o01, o11 in O:
        S00, S01, S11 = S00 + o00, S01 + o01, S11 + o11
    x, y, th = start
    for _ in range(max_iterations):
        c, s = math.cos(th), math.sin(th)
        m0 = m1 = k0 = k1 = h22 = g2 = 0.0
        for (qx, qy), (X, Y), (o00, o01, o11) in zip(q, P, O, strict=True):
            dX, dY = X - x, Y - y
            u, v = c * dX + s * dY, -s * dX + c * dY  # Rz^T (P - t)
            rx, ry = qx - u, qy - v
            a0, a1 = o00 * rx + o01 * ry, o01 * rx + o11 * ry  # O r
            b0, b1 = o01 * u - o00 * v, o11 * u - o01 * v  # O (-v, u)
            m0, m1, k0, k1 = m0 + a0, m1 + a1, k0 + b0, k1 + b1
            h22 += u * b1 - v * b0
            g2 += u * a1 - v * a0
        cc, cs, ss = c * c, c * s, s * s  # rotate the body-frame sums by Rz
        h00 = cc * S00 - 2.0 * cs * S01 + ss * S11
        h01 = cs * (S00 - S11) + (cc - ss) * S01
        h11 = ss * S00 + 2.0 * cs * S01 + cc * S11
        h02, h12 = c * k0 - s * k1, s * k0 + c * k1
        g0, g1 = c * m0 - s * m1, s * m0 + c * m1
        cov = inverse_3x3_sym([h00, h01, h02, h11, h12, h22])
        if cov is None:
            return None
        i00, i01, i02, i11, i12, i22 = cov
        d0 = -(i00 * g0 + i01 * g1 + i02 * g2)
        d1 = -(i01 * g0 + i11 * g1 + i12 * g2)
        d2 = -(i02 * g0 + i12 * g1 + i22 * g2)
        x, y, th = x + d0, y + d1, th + d2
        # the step's length in standard deviations squared: d^T H d = -d^T g
        if -(d0 * g0 + d1 * g1 + d2 * g2) < 1e-6:
            return (x, y, th), cov
    return None


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
