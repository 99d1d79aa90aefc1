"""Where a spot's ray meets the ceiling: the survey's one ray-plane intersection.

Used to carry spots between frames (`survey.observations`), to place landmarks for the
initial guess (`survey.initial`) and to name tracks by geometry (`survey.naming`). Vectorised:
every caller hands all its spots at once (the undistortion through OpenCV is the cost).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, bearings_body_from_pixels
from localizer.types import BoolArray, FloatArray


def ceiling_points_body(
    camera: CameraModel, pixels: npt.ArrayLike, heights_m: npt.ArrayLike
) -> tuple[FloatArray, BoolArray]:
    """Where each pixel's ray meets the plane at its height above the floor, body frame.

    Args:
        pixels: shape (N, 2); heights_m: shape (N,) or a scalar, metres.

    Returns:
        (points (N, 3) metres, hit (N,)): hit is False where the pixel does not invert or its
        ray does not rise to the plane (its point is then undefined).
    """
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    if len(px) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=bool)
    b = bearings_body_from_pixels(camera, px)
    origin = camera.T_body_camera[:3, 3]
    z = np.broadcast_to(np.asarray(heights_m, dtype=np.float64), (len(px),))
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (z - origin[2]) / b[:, 2]
    hit = np.isfinite(s) & (b[:, 2] > 1e-6) & (s > 0)
    points: FloatArray = origin + np.where(hit, s, 1.0)[:, None] * np.nan_to_num(b)
    points[:, 2] = np.where(hit, z, points[:, 2])
    return points, hit


def ceiling_points_world(
    camera: CameraModel, poses: npt.ArrayLike, pixels: npt.ArrayLike, heights_m: npt.ArrayLike
) -> tuple[FloatArray, BoolArray]:
    """The same from body poses (x, y, theta) shape (N, 3) to the world frame."""
    q, hit = ceiling_points_body(camera, pixels, heights_m)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    out = np.empty_like(q)
    out[:, 0] = p[:, 0] + c * q[:, 0] - s * q[:, 1]
    out[:, 1] = p[:, 1] + s * q[:, 0] + c * q[:, 1]
    out[:, 2] = q[:, 2]
    return out, hit
