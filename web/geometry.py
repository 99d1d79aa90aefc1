"""Geometry the viewer draws: uncertainty ellipses, click rays on the ceiling, the camera's
footprint on the ceiling, and a landmark's ceiling position from a spot in a robot's image.

Pure numpy; world frame z up (REP-103), metres, radians.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from commissioning.geometry import points_on_ceiling
from localizer.camera import CameraModel
from localizer.geometry import T_world_body_from_pose
from localizer.types import FloatArray


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
