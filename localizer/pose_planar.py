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

A tilted body is the same problem with the mounting tilted (`pose_tilted`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Literal

from localizer.small_linalg import inverse_3x3_sym

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


RobustLoss = Literal["huber", "cauchy"]
ROBUST_WEIGHTS: dict[RobustLoss, Callable[[float, float], float]] = {
    "huber": huber_weight,
    "cauchy": cauchy_weight,
}


def solve_planar(
    q: list[Point],
    G: list[Mat2],
    P: list[Point],
    start: tuple[float, float, float],
    sigma_px: float | Sequence[float],
    max_iterations: int,
    *,
    loss: RobustLoss | None = None,
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
