"""Geometry the viewer draws: uncertainty ellipses, click rays on the ceiling, the camera's
footprint on the ceiling, and a landmark's ceiling position from a spot in a robot's image.

Pure numpy; world frame z up (REP-103), metres, radians.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, rays_from_pixels
from localizer.geometry import T_world_body_from_pose

FloatArray = npt.NDArray[np.float64]


def ellipse_axes(cov_xy: npt.ArrayLike, *, n_sigma: float = 2.0) -> tuple[float, float, float]:
    """Semi-axes and orientation of the `n_sigma` ellipse of a 2x2 position covariance.

    Args:
        cov_xy: covariance of (x, y), shape (2, 2), m^2.
        n_sigma: scale of the ellipse in standard deviations.

    Returns:
        (semi_major m, semi_minor m, angle of the major axis from +x in radians, (-pi/2, pi/2]).

    Raises:
        ValueError: when the matrix is not 2x2, not finite or not symmetric.
    """
    c = np.asarray(cov_xy, dtype=np.float64)
    if c.shape != (2, 2) or not np.all(np.isfinite(c)):
        raise ValueError(f"ellipse_axes: want a finite 2x2 covariance, got {c.tolist()}")
    if abs(c[0, 1] - c[1, 0]) > 1e-9 * max(1.0, float(np.abs(c).max())):
        raise ValueError(f"ellipse_axes: covariance is not symmetric: {c.tolist()}")
    w, v = np.linalg.eigh(c)
    w = np.clip(w, 0.0, None)
    angle = math.atan2(v[1, 1], v[0, 1])
    if angle <= -math.pi / 2:
        angle += math.pi
    elif angle > math.pi / 2:
        angle -= math.pi
    return n_sigma * math.sqrt(w[1]), n_sigma * math.sqrt(w[0]), angle


def ellipse_points(
    center_xy: npt.ArrayLike, cov_xy: npt.ArrayLike, *, n_sigma: float = 2.0, n_points: int = 32
) -> FloatArray:
    """Closed outline of the uncertainty ellipse, shape (n_points + 1, 2) (first = last)."""
    a, b, angle = ellipse_axes(cov_xy, n_sigma=n_sigma)
    t = np.linspace(0.0, 2.0 * math.pi, n_points + 1)
    local = np.column_stack([a * np.cos(t), b * np.sin(t)])
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s], [s, c]])
    out: FloatArray = local @ R.T + np.asarray(center_xy, dtype=np.float64).reshape(1, 2)
    return out


def ray_plane_point(
    origin: npt.ArrayLike, direction: npt.ArrayLike, height: float
) -> FloatArray | None:
    """Where a ray meets the horizontal plane z = `height`, shape (3,).

    Args:
        origin: ray origin in the world frame, shape (3,), metres.
        direction: ray direction, shape (3,) (need not be unit length).
        height: the plane's z, metres.

    Returns:
        The point, or None when the ray is parallel to the plane or points away from it.
    """
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    if abs(d[2]) < 1e-12:
        return None
    s = float((height - o[2]) / d[2])
    if s < 0.0:
        return None
    return np.asarray(o + s * d, dtype=np.float64)


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


def image_border_pixels(cam: CameraModel, *, per_edge: int = 8) -> FloatArray:
    """Pixels around the image border, clockwise from the top-left corner, shape (4*per_edge, 2)."""
    w, h = cam.width - 0.5, cam.height - 0.5
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)
    top = np.column_stack([-0.5 + t * (w + 0.5), np.full(per_edge, -0.5)])
    right = np.column_stack([np.full(per_edge, w), -0.5 + t * (h + 0.5)])
    bottom = np.column_stack([w - t * (w + 0.5), np.full(per_edge, h)])
    left = np.column_stack([np.full(per_edge, -0.5), h - t * (h + 0.5)])
    return np.vstack([top, right, bottom, left])


def camera_footprint(
    cam: CameraModel, x: float, y: float, theta: float, height: float, *, per_edge: int = 8
) -> FloatArray:
    """The ceiling area the camera sees from a planar pose: a closed polygon, shape (M + 1, 3).

    The image border is unprojected through the lens model and intersected with z = `height`;
    border rays that miss the plane are dropped.
    """
    T = T_world_body_from_pose(x, y, theta)
    pts = points_on_ceiling(cam, T, image_border_pixels(cam, per_edge=per_edge), height)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return np.zeros((0, 3))
    return np.vstack([pts, pts[:1]])


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
