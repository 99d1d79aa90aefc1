"""Where a spot seen by a localized robot lies in the world: pixel rays placed by the robot's
pose and intersected with the ceiling (docs/commissioning.md). Pure: numpy in, numpy out."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, pixels_from_points_camera, rays_from_pixels
from localizer.geometry import T_world_body_from_pose, invert_transform
from localizer.types import BoolArray, FloatArray


def in_view_camera(
    cam: CameraModel,
    p_camera: npt.ArrayLike,
    *,
    margin_px: float,
    max_off_axis_rad: float = math.pi / 2,
) -> BoolArray:
    """Which camera-frame points (N, 3) project into the image, `margin_px` inside its
    border, at most `max_off_axis_rad` from the optical axis; shape (N,)."""
    p = np.asarray(p_camera, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        return np.zeros(0, dtype=bool)
    px, ok = pixels_from_points_camera(cam, p)
    near_axis = p[:, 2] >= math.cos(max_off_axis_rad) * np.linalg.norm(p, axis=1)
    inside = (
        (px[:, 0] >= margin_px - 0.5)
        & (px[:, 0] <= cam.width - 0.5 - margin_px)
        & (px[:, 1] >= margin_px - 0.5)
        & (px[:, 1] <= cam.height - 0.5 - margin_px)
    )
    return np.asarray(ok & inside & near_axis, dtype=bool)


def point_in_view_from_poses(
    cam: CameraModel, poses: npt.ArrayLike, p_world: npt.ArrayLike, *, margin_px: float
) -> BoolArray:
    """Whether one world point (3,) is in view (`in_view_camera`) from each of M body poses
    (x, y, theta), shape (M, 3) -> (M,)."""
    q = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    p = np.asarray(p_world, dtype=np.float64).reshape(3)
    dx, dy = p[0] - q[:, 0], p[1] - q[:, 1]
    c, s = np.cos(q[:, 2]), np.sin(q[:, 2])
    p_body = np.stack([c * dx + s * dy, -s * dx + c * dy, np.full(len(q), p[2])], axis=1)
    T_camera_body = invert_transform(cam.T_body_camera)
    p_camera = p_body @ T_camera_body[:3, :3].T + T_camera_body[:3, 3]
    return in_view_camera(cam, p_camera, margin_px=margin_px)


def rays_world(cam: CameraModel, T_world_body: FloatArray, pixels: npt.ArrayLike) -> FloatArray:
    """Unit rays of pixels in the world frame for a body pose; pixels (N, 2) -> (N, 3)."""
    R_world_camera = (T_world_body @ cam.T_body_camera)[:3, :3]
    return rays_from_pixels(cam, pixels) @ R_world_camera.T


def points_on_ceiling(
    cam: CameraModel, T_world_body: FloatArray, pixels: npt.ArrayLike, height: float
) -> FloatArray:
    """World points where the rays of `pixels` meet the plane z = `height`.

    Args:
        T_world_body: body pose, shape (4, 4).
        pixels: shape (N, 2), (col, row).
        height: the plane's z in the world frame, metres (above the camera).

    Returns:
        shape (N, 3); rows whose ray does not reach the plane are NaN.
    """
    origin = (T_world_body @ cam.T_body_camera)[:3, 3]
    rays = rays_world(cam, T_world_body, pixels)
    out = np.full((len(rays), 3), np.nan)
    ok = rays[:, 2] > 1e-9
    s = (height - origin[2]) / np.where(ok, rays[:, 2], 1.0)
    ok &= s > 0.0
    out[ok] = origin + s[ok, None] * rays[ok]
    return out


def landmark_from_spot(
    cam: CameraModel, x: float, y: float, theta: float, pixel: npt.ArrayLike, height: float
) -> FloatArray | None:
    """A landmark's world position from its spot in the image of a localized robot.

    The spot's ray from the camera, placed by the robot's pose (x, y, theta), is intersected
    with the ceiling at `height` (the landmark's LED height).

    Args:
        pixel: the spot's centroid (col, row), shape (2,).
        height: the LED's z in the world frame, metres.

    Returns:
        shape (3,), or None when the ray does not reach that height.
    """
    T = T_world_body_from_pose(x, y, theta)
    p = points_on_ceiling(cam, T, np.asarray(pixel, dtype=np.float64).reshape(1, 2), height)[0]
    return p if np.all(np.isfinite(p)) else None
