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
"""

from __future__ import annotations

import math

Point = tuple[float, float]
Mat2 = tuple[float, float, float, float]  # row-major a00 a01 a10 a11


def floor_points(
    m: list[Point],
    A: list[Mat2],
    z: list[float],
    T_body_camera: list[list[float]],
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


def inverse_3x3_sym(H: list[float]) -> list[float] | None:
    """Inverse of a symmetric 3x3 matrix given as (h00 h01 h02 h11 h12 h22); None if singular."""
    a, b, c, d, e, f = H
    A00, A01, A02 = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A00 + b * A01 + c * A02
    if not math.isfinite(det) or det <= 1e-300 * max(1.0, a * d * f):
        return None
    A11, A12, A22 = a * f - c * c, b * c - a * e, a * d - b * b
    return [A00 / det, A01 / det, A02 / det, A11 / det, A12 / det, A22 / det]


def solve_planar(
    q: list[Point],
    G: list[Mat2],
    P: list[Point],
    start: tuple[float, float, float],
    sigma_px: float,
    max_iterations: int,
) -> tuple[tuple[float, float, float], list[float], float] | None:
    """Gauss-Newton for (x, y, theta) minimising sum |G_i^-1 (q_i - Rz^T (P_i - t))|^2 / sigma^2.

    Returns:
        ((x, y, theta), covariance as (c00 c01 c02 c11 c12 c22), residual RMS in pixels),
        or None when singular or not converged.
    """
    W: list[Mat2] = []
    for g00, g01, g10, g11 in G:
        det = (g00 * g11 - g01 * g10) * sigma_px
        if det == 0.0:
            return None
        W.append((g11 / det, -g01 / det, -g10 / det, g00 / det))
    x, y, th = start
    for _ in range(max_iterations):
        c, s = math.cos(th), math.sin(th)
        h00 = h01 = h02 = h11 = h12 = h22 = g0 = g1 = g2 = ee = 0.0
        for (qx, qy), (X, Y), (w00, w01, w10, w11) in zip(q, P, W, strict=True):
            dX, dY = X - x, Y - y
            u, v = c * dX + s * dY, -s * dX + c * dY  # Rz^T (P - t)
            rx, ry = qx - u, qy - v
            # d(residual)/d(x, y, theta) = -d(u, v)/d(...) = (c, -s), (s, c), (-v, u)
            e0, e1 = w00 * rx + w01 * ry, w10 * rx + w11 * ry
            ee += e0 * e0 + e1 * e1
            j00, j10 = w00 * c - w01 * s, w10 * c - w11 * s
            j01, j11 = w00 * s + w01 * c, w10 * s + w11 * c
            j02, j12 = -w00 * v + w01 * u, -w10 * v + w11 * u
            h00 += j00 * j00 + j10 * j10
            h01 += j00 * j01 + j10 * j11
            h02 += j00 * j02 + j10 * j12
            h11 += j01 * j01 + j11 * j11
            h12 += j01 * j02 + j11 * j12
            h22 += j02 * j02 + j12 * j12
            g0 += j00 * e0 + j10 * e1
            g1 += j01 * e0 + j11 * e1
            g2 += j02 * e0 + j12 * e1
        cov = inverse_3x3_sym([h00, h01, h02, h11, h12, h22])
        if cov is None:
            return None
        i00, i01, i02, i11, i12, i22 = cov
        d0 = -(i00 * g0 + i01 * g1 + i02 * g2)
        d1 = -(i01 * g0 + i11 * g1 + i12 * g2)
        d2 = -(i02 * g0 + i12 * g1 + i22 * g2)
        x, y, th = x + d0, y + d1, th + d2
        # the step's length in standard deviations squared: d^T H d = -d^T g
        step2 = -(d0 * g0 + d1 * g1 + d2 * g2)
        if step2 < 1e-6:
            break
    else:
        return None
    # residual after the last step, to first order: |e + J d|^2 = |e|^2 - d^T H d
    rms = sigma_px * math.sqrt(max(ee - step2, 0.0) / len(q))
    return (x, y, th), cov, rms
