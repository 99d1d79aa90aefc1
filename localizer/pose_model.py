"""The observation model behind the pose solver: where a ceiling landmark appears in the
undistorted normalised image for a body pose, and its Jacobian.

The body pose is planar (x, y, theta) plus an optional tilt (roll, pitch) of the body:
R_world_body = Rz(theta) Ry(pitch) Rx(roll), body origin at (x, y, 0). A landmark P (world)
is seen in the camera frame at

    p_c = R_body_camera^T (R_world_body^T (P - t) - t_body_camera),  t = (x, y, 0),

and in normalised image coordinates at m = (p_c,x / p_c,z, p_c,y / p_c,z): the 3D
generalisation of the paper's eq. (3), which `camera.predict_pixels` takes on to pixels
through the lens model.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


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


def observation_model(
    params: FloatArray, p_world: FloatArray, T_body_camera: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Landmarks in the camera frame and their normalised image coordinates.

    Args:
        params: (x, y, theta) or (x, y, theta, roll, pitch); metres and radians.
        p_world: landmark positions, shape (N, 3).
        T_body_camera: camera mounting, shape (4, 4).

    Returns:
        (p_camera shape (N, 3), m shape (N, 2) = p_camera[:, :2] / p_camera[:, 2:]).
    """
    roll, pitch = (params[3], params[4]) if len(params) == 5 else (0.0, 0.0)
    R_wb = rotation_world_body(params[2], roll, pitch)
    d = p_world.copy()
    d[:, 0] -= params[0]
    d[:, 1] -= params[1]
    p_body = d @ R_wb  # rows: R_wb^T (P - t)
    p_camera = (p_body - T_body_camera[:3, 3]) @ T_body_camera[:3, :3]
    return p_camera, p_camera[:, :2] / p_camera[:, 2:3]


def jacob_h(
    params: FloatArray, p_world: FloatArray, T_body_camera: FloatArray, p_camera: FloatArray
) -> FloatArray:
    """d m / d params of `observation_model`, shape (N, 2, len(params)).

    Args:
        params, p_world, T_body_camera: as `observation_model`.
        p_camera: its first output at `params`, shape (N, 3).
    """
    theta = params[2]
    tilted = len(params) == 5
    roll, pitch = (params[3], params[4]) if tilted else (0.0, 0.0)
    cz, sz = math.cos(theta), math.sin(theta)
    cy, sy = math.cos(pitch), math.sin(pitch)
    cx, sx = math.cos(roll), math.sin(roll)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    Ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    R_t = Ry @ Rx
    # v = Rz^T (P - t) (rows), the landmark in the level, heading-aligned frame
    d = p_world[:, :2] - params[:2]
    v = np.column_stack([cz * d[:, 0] + sz * d[:, 1], -sz * d[:, 0] + cz * d[:, 1]])
    n = len(p_world)
    dv = np.zeros((n, 3, len(params)))  # d(R_t^T v) before R_t^T is applied, per param
    dv[:, 0, 0], dv[:, 1, 0] = -cz, sz  # d v / d x = -Rz^T e_x
    dv[:, 0, 1], dv[:, 1, 1] = -sz, -cz  # d v / d y = -Rz^T e_y
    dv[:, 0, 2], dv[:, 1, 2] = v[:, 1], -v[:, 0]  # d v / d theta = -e_z x v
    dp_body = np.einsum("ji,njk->nik", R_t, dv)  # R_t^T dv
    if tilted:
        vz = p_world[:, 2]
        p_body = np.column_stack([v, vz]) @ R_t  # R_t^T v
        # d(R_t^T v)/d roll = -e_x x (R_t^T v);  d/d pitch = -Rx^T (e_y x (Ry^T v))
        dp_body[:, 1, 3], dp_body[:, 2, 3] = p_body[:, 2], -p_body[:, 1]
        w = np.column_stack([v, vz]) @ Ry  # Ry^T v
        ey_cross_w = np.column_stack([w[:, 2], np.zeros(n), -w[:, 0]])
        dp_body[:, :, 4] = -(ey_cross_w @ Rx)  # rows: Rx^T (e_y x w)
    dp_camera = np.einsum("ji,njk->nik", T_body_camera[:3, :3], dp_body)
    z = p_camera[:, 2:3, None]
    m = (p_camera[:, :2] / p_camera[:, 2:3])[:, :, None]
    J: FloatArray = (dp_camera[:, :2, :] - m * dp_camera[:, 2:3, :]) / z
    return J
