"""The part of the ceiling a robot's camera can use, for drawing: its field of view limited
to the lens's usable angle and to the building.

A fisheye's image border reaches far beyond where an LED is still detected (its emission
and the lens's vignetting fall off with the angle from the optical axis), and beyond the
walls. The outline drawn is the image border, each border ray pulled in to at most
`max_off_axis_rad` from the optical axis (the same bound `commissioning.doubt` judges by), met with
the ceiling plane, then clipped to the site's rectangle.

Pure numpy; world frame z up (REP-103), metres, radians.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel, rays_from_pixels
from localizer.types import FloatArray
from web.geometry import image_border_pixels

Bounds = tuple[float, float, float, float]
"""x_min, x_max, y_min, y_max, metres."""


def clamp_off_axis(rays: FloatArray, max_off_axis_rad: float) -> FloatArray:
    """Unit rays in the camera frame (N, 3), each turned toward the optical axis (+z) to at
    most `max_off_axis_rad` from it, keeping its azimuth."""
    r: FloatArray = np.asarray(rays, dtype=np.float64).reshape(-1, 3)
    r = r / np.linalg.norm(r, axis=1, keepdims=True)
    angle = np.arccos(np.clip(r[:, 2], -1.0, 1.0))
    limit = min(max_off_axis_rad, math.pi / 2 - 1e-3)
    over = angle > limit
    if not np.any(over):
        return r
    az = np.arctan2(r[over, 1], r[over, 0])
    s = math.sin(limit)
    r[over] = np.column_stack([s * np.cos(az), s * np.sin(az), np.full(len(az), math.cos(limit))])
    return r


def usable_footprint_body(
    cam: CameraModel, ceiling_z: float, *, max_off_axis_rad: float, per_edge: int = 12
) -> FloatArray:
    """The ceiling area the camera can use, in the body frame: closed polygon (M + 1, 3).

    Args:
        cam: the robot's camera (lens and mounting `T_body_camera`).
        ceiling_z: the ceiling's height above the floor (the body frame's z = 0), metres.
        max_off_axis_rad: the usable half-angle around the optical axis, radians.
        per_edge: border samples per image edge.
    """
    rays_cam = clamp_off_axis(
        rays_from_pixels(cam, image_border_pixels(cam, per_edge=per_edge)), max_off_axis_rad
    )
    R, origin = cam.T_body_camera[:3, :3], cam.T_body_camera[:3, 3]
    rays = rays_cam @ R.T
    ok = rays[:, 2] > 1e-9
    s = (ceiling_z - origin[2]) / np.where(ok, rays[:, 2], 1.0)
    ok &= s > 0.0
    pts = origin + s[ok, None] * rays[ok]
    if len(pts) == 0:
        return np.zeros((0, 3))
    return np.vstack([pts, pts[:1]])


def clip_polygon_to_rect(poly_xy: FloatArray, bounds: Bounds) -> FloatArray:
    """A polygon (N, 2), open or closed, clipped to an axis-aligned rectangle
    (Sutherland-Hodgman); returns the open clipped polygon (M, 2), empty when outside."""
    x0, x1, y0, y1 = bounds
    pts = np.asarray(poly_xy, dtype=np.float64).reshape(-1, 2)
    if len(pts) > 1 and np.array_equal(pts[0], pts[-1]):
        pts = pts[:-1]
    # each side of the rectangle: (axis, limit, +1 keeps >= limit / -1 keeps <= limit)
    for axis, limit, sign in ((0, x0, 1.0), (0, x1, -1.0), (1, y0, 1.0), (1, y1, -1.0)):
        if len(pts) == 0:
            break
        inside = sign * (pts[:, axis] - limit) >= 0.0
        out: list[FloatArray] = []
        for i in range(len(pts)):
            cur, prev = pts[i], pts[i - 1]
            if inside[i] != inside[i - 1]:  # the edge crosses this side: add the crossing
                t = (limit - prev[axis]) / (cur[axis] - prev[axis])
                out.append(prev + t * (cur - prev))
            if inside[i]:
                out.append(cur)
        pts = np.array(out, dtype=np.float64).reshape(-1, 2)
    return pts


def footprint_in_site(
    foot_body: FloatArray, x: float, y: float, theta: float, bounds: Bounds
) -> FloatArray | None:
    """The body-frame footprint clipped to the site at a pose, in the body frame again
    (closed, (M + 1, 3)); None when it lies wholly inside (draw it unclipped)."""
    if len(foot_body) == 0:
        return None
    c, s = math.cos(theta), math.sin(theta)
    R = np.array([[c, -s], [s, c]])
    world = foot_body[:, :2] @ R.T + np.array([x, y])
    x0, x1, y0, y1 = bounds
    if (
        world[:, 0].min() >= x0
        and world[:, 0].max() <= x1
        and world[:, 1].min() >= y0
        and world[:, 1].max() <= y1
    ):
        return None
    clipped = clip_polygon_to_rect(world, bounds)
    if len(clipped) == 0:
        return np.zeros((0, 3))
    body = (clipped - np.array([x, y])) @ R
    z = float(foot_body[0, 2])
    out = np.column_stack([body, np.full(len(body), z)])
    return np.vstack([out, out[:1]])
