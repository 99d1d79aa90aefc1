"""Coverage of a landmark layout: how many landmarks the camera sees at each floor point, the
position error to expect there, and landmark pairs spaced outside the paper's range.

The expected error is the linearised least-squares covariance of (x, y, theta) from the
visible landmarks' pixels with isotropic pixel noise: `sigma_px^2 (J^T J)^-1`, with J the
Jacobian of the predicted pixels (eq. 3 in 3D, `predict_pixels`) with respect to the pose.
With two landmarks this is the paper's two-landmark geometry (Sec. IV-A, eqs. 1-2): the
error grows as the baseline shrinks and the ceiling rises.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import rotation_z
from localizer.types import BoolArray, FloatArray, IntArray


@dataclass(frozen=True)
class CoverageConfig:
    """Coverage settings.

    Attributes:
        step_m: grid spacing on the floor, metres.
        margin_m: grid extends this far beyond the landmarks' bounding box, metres.
        n_headings: robot headings tried at each point (evenly spaced); the worst counts.
        pixel_sigma_px: spot centroid noise, pixels (1 sigma).
        delta_m, delta_rad: finite-difference steps of the Jacobian.
        max_points: refuse grids larger than this (a too-fine step on a big site).
    """

    step_m: float = 0.25
    margin_m: float = 1.0
    n_headings: int = 4
    pixel_sigma_px: float = 0.3
    delta_m: float = 1e-4
    delta_rad: float = 1e-4
    max_points: int = 40_000

    def __post_init__(self) -> None:
        if not (math.isfinite(self.step_m) and self.step_m > 0):
            raise ValueError(f"coverage: step_m must be positive, got {self.step_m!r}")
        if self.n_headings < 1:
            raise ValueError(f"coverage: n_headings must be >= 1, got {self.n_headings!r}")


@dataclass(frozen=True, eq=False)
class Coverage:
    """Coverage on a floor grid.

    Attributes:
        xs: grid x coordinates, shape (W,), metres.
        ys: grid y coordinates, shape (H,), metres.
        counts: landmarks in view, fewest over the headings tried, shape (H, W).
        error_m: expected 1-sigma position error sqrt(var x + var y), worst over the headings,
            shape (H, W), metres; NaN where fewer than two landmarks are seen.
    """

    xs: FloatArray
    ys: FloatArray
    counts: IntArray
    error_m: FloatArray


def _pixels_at(
    cam: CameraModel, p_world: FloatArray, xy: FloatArray, theta: float
) -> tuple[FloatArray, BoolArray]:
    """Pixels of every landmark from every grid pose at one heading.

    Args:
        p_world: landmarks, shape (N, 3).
        xy: body positions, shape (G, 2).

    Returns:
        (pixels shape (G, N, 2), valid shape (G, N)).
    """
    R_wb = rotation_z(theta)
    R_wc = R_wb @ cam.T_body_camera[:3, :3]
    t_wc = np.column_stack([xy, np.zeros(len(xy))]) + R_wb @ cam.T_body_camera[:3, 3]
    p_cam = (p_world[None, :, :] - t_wc[:, None, :]) @ R_wc  # R_wc^T (p - t), row-wise
    px, valid = pixels_from_points_camera(cam, p_cam.reshape(-1, 3))
    n = len(p_world)
    return px.reshape(len(xy), n, 2), valid.reshape(len(xy), n)


def _heading_coverage(
    cam: CameraModel, p_world: FloatArray, xy: FloatArray, theta: float, cfg: CoverageConfig
) -> tuple[IntArray, FloatArray]:
    px0, valid = _pixels_at(cam, p_world, xy, theta)
    steps = (
        (np.array([cfg.delta_m, 0.0]), 0.0, cfg.delta_m),
        (np.array([0.0, cfg.delta_m]), 0.0, cfg.delta_m),
        (np.zeros(2), cfg.delta_rad, cfg.delta_rad),
    )
    J = np.zeros((len(xy), len(p_world), 2, 3))
    for k, (dxy, dtheta, h) in enumerate(steps):
        px1, valid1 = _pixels_at(cam, p_world, xy + dxy, theta + dtheta)
        valid &= valid1
        J[..., k] = (px1 - px0) / h
    J[~valid] = 0.0
    counts = valid.sum(axis=1).astype(np.int64)
    info = np.einsum("gnij,gnik->gjk", J, J)  # (G, 3, 3)
    error = np.full(len(xy), np.nan)
    ok = counts >= 2
    if np.any(ok):
        cov = np.linalg.pinv(info[ok], hermitian=True) * cfg.pixel_sigma_px**2
        error[ok] = np.sqrt(np.clip(cov[:, 0, 0] + cov[:, 1, 1], 0.0, None))
    return counts, error


def coverage_grid(
    cam: CameraModel,
    positions: npt.ArrayLike,
    config: CoverageConfig | None = None,
    *,
    bounds: tuple[float, float, float, float] | None = None,
) -> Coverage:
    """Count the landmarks in view and the expected error over a floor grid.

    Args:
        cam: the robot's camera, with its mounting (`T_body_camera`).
        positions: landmark positions in the world frame, shape (N, 3), metres.
        config: grid and noise settings.
        bounds: (x_min, x_max, y_min, y_max) of the grid, metres; default: the landmarks'
            bounding box grown by `config.margin_m`.

    Raises:
        ValueError: when the grid would have more than `config.max_points` points, or
            `bounds` is empty and there are no landmarks.
    """
    cfg = config or CoverageConfig()
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if bounds is None:
        if len(p) == 0:
            raise ValueError("coverage: no landmarks and no bounds given")
        lo, hi = p[:, :2].min(axis=0) - cfg.margin_m, p[:, :2].max(axis=0) + cfg.margin_m
        bounds = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
    x0, x1, y0, y1 = bounds
    xs = np.arange(x0, x1 + 1e-9, cfg.step_m)
    ys = np.arange(y0, y1 + 1e-9, cfg.step_m)
    if len(xs) * len(ys) > cfg.max_points:
        raise ValueError(
            f"coverage: a {len(xs)}x{len(ys)} grid exceeds max_points={cfg.max_points}; "
            f"raise step_m (now {cfg.step_m} m)"
        )
    gx, gy = np.meshgrid(xs, ys)
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    counts = np.full(len(xy), np.iinfo(np.int64).max, dtype=np.int64)
    error = np.full(len(xy), -np.inf)
    if len(p) == 0:
        counts[:] = 0
        error[:] = np.nan
    for theta in np.arange(cfg.n_headings) * (2.0 * math.pi / cfg.n_headings):
        if len(p) == 0:
            break
        c, e = _heading_coverage(cam, p, xy, float(theta), cfg)
        counts = np.minimum(counts, c)
        error = np.where(np.isnan(e) | np.isnan(error), np.nan, np.maximum(error, e))
    shape = (len(ys), len(xs))
    return Coverage(xs, ys, counts.reshape(shape), error.reshape(shape))


@dataclass(frozen=True)
class SpacingFlag:
    """A landmark pair spaced outside the recommended range.

    Attributes:
        a, b: the landmark IDs (a < b).
        distance_m: their horizontal distance, metres.
        problem: "too_close" or "too_far" (b is a's nearest neighbour, beyond the maximum).
        allowed_m: (min, max) spacing for this pair's ceiling height, metres.
    """

    a: int
    b: int
    distance_m: float
    problem: str
    allowed_m: tuple[float, float]


def spacing_flags(
    ids: npt.ArrayLike,
    positions: npt.ArrayLike,
    *,
    min_spacing_m: float = 0.30,
    max_spacing_m: float = 1.50,
    reference_height_m: float = 2.5,
) -> list[SpacingFlag]:
    """Landmark pairs outside the paper's 30-150 cm spacing (for a 2.5 m ceiling).

    The range scales with the pair's mean LED height over `reference_height_m` (the spots'
    image separation scales with spacing / height). Pairs closer than the minimum are
    flagged "too_close"; a landmark whose nearest neighbour lies beyond the maximum is
    flagged "too_far" with that neighbour.

    Args:
        ids: shape (N,).
        positions: shape (N, 3), metres.
    """
    i = np.asarray(ids, dtype=np.int64).reshape(-1)
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(i) != len(p):
        raise ValueError(f"spacing_flags: {len(i)} ids but {len(p)} positions")
    if len(p) < 2:
        return []
    d = np.linalg.norm(p[:, None, :2] - p[None, :, :2], axis=2)
    scale = 0.5 * (p[:, None, 2] + p[None, :, 2]) / reference_height_m
    lo, hi = min_spacing_m * scale, max_spacing_m * scale
    flags: dict[tuple[int, int], SpacingFlag] = {}
    n = len(p)
    for a in range(n):
        for b in range(a + 1, n):
            if d[a, b] < lo[a, b]:
                key = (int(min(i[a], i[b])), int(max(i[a], i[b])))
                rng = (float(lo[a, b]), float(hi[a, b]))
                flags[key] = SpacingFlag(*key, float(d[a, b]), "too_close", rng)
    np.fill_diagonal(d, np.inf)
    for a in range(n):
        b = int(np.argmin(d[a]))
        if d[a, b] > hi[a, b]:
            key = (int(min(i[a], i[b])), int(max(i[a], i[b])))
            rng = (float(lo[a, b]), float(hi[a, b]))
            flags.setdefault(key, SpacingFlag(*key, float(d[a, b]), "too_far", rng))
    return sorted(flags.values(), key=lambda f: (f.a, f.b))
