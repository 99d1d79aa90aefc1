"""Rigid transforms in the plane and in space: one `wrap_angle`, one place.

Conventions (docs/conventions.md): metres, radians, REP-103 heading in (-pi, pi]
counter-clockwise from world +x; transforms are named `T_<target>_<source>` and map
points from the source frame into the target frame (p_target = T_target_source @ p_source).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from localizer.types import FloatArray


def wrap_angle(angle: float | FloatArray) -> float | FloatArray:
    """Wrap an angle or an array of angles to (-pi, pi].

    Args:
        angle: radians, a scalar or any shape.

    Returns:
        The same angle(s) in (-pi, pi]; a float for a float input.
    """
    if type(angle) is float or isinstance(angle, float | int):  # scalars: ~20x faster as floats
        a = float(angle)
        if -math.pi < a <= math.pi:
            return a
        a = math.pi - (math.pi - a) % (2.0 * math.pi)
        return a + 2.0 * math.pi if a <= -math.pi else a
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=np.float64), 2.0 * np.pi)
    # np.mod can round up to exactly 2 pi for angles a hair above pi, giving -pi: fold it back
    wrapped = np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)
    if np.ndim(wrapped) == 0:
        return float(wrapped)
    return wrapped


def rotation_z(theta: float) -> FloatArray:
    """Rotation matrix about +z by `theta` radians, shape (3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_2d(theta: float) -> FloatArray:
    """Planar rotation matrix by `theta` radians, shape (2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def T_world_body_from_pose(x: float, y: float, theta: float) -> FloatArray:
    """Homogeneous transform of a planar body pose, shape (4, 4).

    The body frame sits on the floor (z = 0) at (x, y) with heading `theta`.
    """
    T = np.eye(4)
    T[:3, :3] = rotation_z(theta)
    T[0, 3] = x
    T[1, 3] = y
    return T


def pose_from_T_world_body(T_world_body: FloatArray) -> tuple[float, float, float]:
    """Planar pose (x, y, theta) of a (4, 4) transform, heading from its x axis."""
    theta = float(np.arctan2(T_world_body[1, 0], T_world_body[0, 0]))
    return float(T_world_body[0, 3]), float(T_world_body[1, 3]), float(wrap_angle(theta))


def invert_transform(T: FloatArray) -> FloatArray:
    """Inverse of a rigid (4, 4) transform."""
    R = T[:3, :3]
    T_inv = np.eye(4)
    T_inv[:3, :3] = R.T
    T_inv[:3, 3] = -R.T @ T[:3, 3]
    return T_inv


def transform_points(T: FloatArray, points: FloatArray) -> FloatArray:
    """Apply a (4, 4) rigid transform to points of shape (N, 3); returns (N, 3)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return pts @ T[:3, :3].T + T[:3, 3]


def check_transform(T: npt.ArrayLike, name: str) -> FloatArray:
    """Validate a rigid transform, raising ValueError that names `name` and the fault."""
    arr = np.asarray(T, dtype=np.float64)
    if arr.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 transform, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: transform has non-finite entries")
    if not np.allclose(arr[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1], got {arr[3].tolist()}")
    R = arr[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError(f"{name}: upper-left 3x3 block is not a rotation matrix")
    return arr
