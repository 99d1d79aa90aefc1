"""What a robot's upward camera sees of the ceiling from a planar pose: its reach, which
landmarks fall inside the image with a margin to spare, and how far from the image centre
(pure geometry, numpy in and out; the LED planner `lighting.policy` asks it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.types import BoolArray, FloatArray


def body_pose(x: float, y: float, theta: float) -> FloatArray:
    """T_world_body (4, 4) of a planar pose."""
    c, s = math.cos(theta), math.sin(theta)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = (x, y)
    return T


def view_reach_m(camera: CameraModel, ceiling_m: float) -> float:
    """How far from the camera's ceiling point a landmark can be and still be seen, metres
    (the image corner's ray at the ceiling; bounded for a fisheye)."""
    height = max(ceiling_m - float(camera.T_body_camera[2, 3]), 0.5)
    half_diag = math.hypot(camera.width, camera.height) / 2
    angle = min(max(math.atan2(half_diag, camera.fu), half_diag / camera.fu), math.radians(75.0))
    offset = math.hypot(*camera.T_body_camera[:2, 3])
    return height * math.tan(angle) + offset


def in_view(
    camera: CameraModel,
    pose: tuple[float, float, float],
    positions: FloatArray,
    margin_m: float,
    ceiling_m: float,
) -> tuple[BoolArray, FloatArray]:
    """Which landmarks a camera sees from a planar pose with `margin_m` to spare, and their
    distance from the image centre in pixels.

    Args:
        positions: landmark positions, shape (N, 3).

    Returns:
        (visible shape (N,), centre distance in pixels shape (N,)).
    """
    px, valid = project_from_poses(camera, [pose], positions)
    ok, centre = visible(camera, px, valid, margin_m, ceiling_m)
    return ok[0], centre[0]


def project_from_poses(
    camera: CameraModel, poses: Sequence[tuple[float, float, float]], positions: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """The landmarks' pixels seen from each planar pose, in one projection.

    Returns:
        (pixels shape (S, N, 2), valid shape (S, N)) for S poses and N positions.
    """
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    xyt = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    c, s = np.cos(xyt[:, 2]), np.sin(xyt[:, 2])
    R_wb = np.zeros((len(xyt), 3, 3))  # planar body poses: a turn about z
    R_wb[:, 0, 0], R_wb[:, 0, 1], R_wb[:, 1, 0], R_wb[:, 1, 1] = c, -s, s, c
    R_wb[:, 2, 2] = 1.0
    T_bc = camera.T_body_camera
    R_wc = R_wb @ T_bc[:3, :3]  # world from camera, per pose
    t_wc = R_wb @ T_bc[:3, 3] + np.column_stack([xyt[:, :2], np.zeros(len(xyt))])
    p_camera = np.einsum("sji,snj->sni", R_wc, P[None, :, :] - t_wc[:, None, :])
    px, valid = pixels_from_points_camera(camera, p_camera.reshape(-1, 3))
    return px.reshape(len(xyt), len(P), 2), valid.reshape(len(xyt), len(P))


def visible(
    camera: CameraModel,
    px: FloatArray,
    valid: BoolArray,
    margin_m: float,
    ceiling_m: float,
) -> tuple[BoolArray, FloatArray]:
    """`in_view` of projected pixels (any leading shape, (..., 2)): inside the image with
    `margin_m` to spare, and the distance from the image centre (inf when not)."""
    height = max(ceiling_m - float(camera.T_body_camera[2, 3]), 0.5)
    margin_px = margin_m * camera.fu / height
    w, h = camera.width, camera.height
    u, v = px[..., 0], px[..., 1]
    ok = valid & (u >= margin_px) & (u <= w - 1 - margin_px) & (v >= margin_px)
    ok &= v <= h - 1 - margin_px
    centre = np.hypot(u - camera.cu, v - camera.cv)
    return ok, np.where(ok, centre, np.inf)
