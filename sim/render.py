"""The 8-bit IR frame an upward camera sees: point-source LEDs and extended IR sources.

Every source is projected through `localizer.camera.predict_pixels`, so both lens models and
any mounting (offset, yaw, tilt) or tilted body pose work unchanged. A point source becomes a
Gaussian point-spread spot integrated over each pixel's area (with `erf`), so the
intensity-weighted centroid of a background-free, unsaturated spot lies on the projected pixel.
Its brightness falls with the distance and with the angle from the optical axis (the LED's
emission pattern and the lens's vignetting folded into one `cos(angle) ** n` law). Extended
sources (a halogen lamp, a sunlight patch) are filled outlines with a soft edge. The sensor
adds a constant background, Gaussian read noise and clips at saturation.

Noise comes from a small pool of pre-drawn dark frames (one picked per frame, with a random
offset) and sources are added patch by patch, so a frame costs one 300 kB copy plus its
patches, not 300 000 normal draws and full-frame float arithmetic.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.special import erf

from localizer.camera import CameraModel, T_camera_world, pixels_from_points_camera
from localizer.geometry import transform_points
from localizer.types import BoolArray, FloatArray, ImageU8

_NOISE_POOL_SEED = 0x1D5EED


@dataclass(frozen=True)
class RenderConfig:
    """Optics and sensor of the simulated IR camera.

    Attributes:
        psf_sigma_px: standard deviation of the Gaussian point-spread function, pixels.
        peak_counts: peak pixel value above background of a nominal LED (intensity 1.0) seen
            on the optical axis at `nominal_distance_m`, for a spot centred on a pixel.
        nominal_distance_m: distance at which intensity 1.0 gives `peak_counts`, metres.
        falloff_exponent: brightness falls as cos(angle from the optical axis) ** this.
        background_counts: mean dark level of the sensor, counts.
        noise_sigma_counts: standard deviation of the read noise, counts (0: none).
        saturation_counts: the sensor's full scale (8 bit: 255).
        min_spot_counts: a spot's tail is drawn out to where it falls below this, counts.
        max_spot_radius_px: cap on a spot's drawn radius, pixels.
        extended_edge_sigma_px: blur of the edge of extended sources, pixels.
        noise_pool_frames: how many pre-drawn noise frames to pick from.
        noise_pool_margin_px: extra rows/columns of each pool frame (room for the random
            offset that decorrelates consecutive frames).
    """

    psf_sigma_px: float = 1.1
    peak_counts: float = 170.0
    nominal_distance_m: float = 2.5
    falloff_exponent: float = 4.0
    background_counts: float = 10.0
    noise_sigma_counts: float = 2.0
    saturation_counts: float = 255.0
    min_spot_counts: float = 0.25
    max_spot_radius_px: int = 15
    extended_edge_sigma_px: float = 1.5
    noise_pool_frames: int = 8
    noise_pool_margin_px: int = 32

    def __post_init__(self) -> None:
        for name in ("psf_sigma_px", "peak_counts", "nominal_distance_m", "saturation_counts"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"RenderConfig: {name} must be positive, got {v!r}")
        for name in ("falloff_exponent", "background_counts", "noise_sigma_counts"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"RenderConfig: {name} must be >= 0, got {v!r}")
        if self.noise_pool_frames < 1 or self.noise_pool_margin_px < 0:
            raise ValueError("RenderConfig: noise pool needs >= 1 frame and a margin >= 0")

    @property
    def nominal_flux_counts(self) -> float:
        """Total counts of a nominal spot (its peak pixel holds `peak_counts`)."""
        centre_fraction = erf(0.5 / (self.psf_sigma_px * math.sqrt(2.0))) ** 2
        return float(self.peak_counts / centre_fraction)


@dataclass(frozen=True, eq=False)
class ExtendedSource:
    """An IR source with an area: a flat outline in the world, filled with one brightness.

    Attributes:
        outline_world: the outline's corners (a polygon), metres, shape (M, 3), M >= 3.
        brightness_counts: level above background inside the outline; values above the
            saturation level give a saturated blob.
        name: what it is (e.g. "halogen lamp"), for messages and viewers.
    """

    outline_world: FloatArray
    brightness_counts: float
    name: str = "extended source"

    def __post_init__(self) -> None:
        pts = np.asarray(self.outline_world, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 3 or not np.all(np.isfinite(pts)):
            raise ValueError(f"{self.name}: outline must be (M>=3, 3) finite, got {pts.shape}")
        pts.setflags(write=False)
        object.__setattr__(self, "outline_world", pts)


def disc_outline(
    center_world: Sequence[float], radius_m: float, *, segments: int = 32
) -> FloatArray:
    """Corners of a horizontal disc (a lamp's face, a round patch), shape (segments, 3)."""
    a = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    c = np.asarray(center_world, dtype=np.float64)
    return np.column_stack(
        [c[0] + radius_m * np.cos(a), c[1] + radius_m * np.sin(a), np.full(segments, c[2])]
    )


@functools.lru_cache(maxsize=4)
def _noise_pool(
    height: int, width: int, background: float, sigma: float, frames: int, margin: int
) -> ImageU8:
    """Pre-drawn dark frames (background + read noise, rounded and clipped), uint8,
    shape (frames, height + margin, width + margin)."""
    rng = np.random.default_rng(_NOISE_POOL_SEED)
    noise = rng.normal(background, sigma, size=(frames, height + margin, width + margin))
    pool: ImageU8 = np.clip(np.rint(noise), 0, 255).astype(np.uint8)
    pool.setflags(write=False)
    return pool


def _dark_frame(
    camera: CameraModel, rng: np.random.Generator | None, config: RenderConfig
) -> npt.NDArray[np.float32] | ImageU8:
    """The frame before any source is drawn.

    Without noise: float32 background, sources added exactly, rounded once at the end.
    With noise: a uint8 frame cut at a random offset from a random pool frame; sources are
    then added patch by patch (rounded and clipped per patch), so a frame costs one 300 kB
    copy plus its patches.
    """
    h, w = camera.height, camera.width
    if rng is None or config.noise_sigma_counts == 0:
        return np.full((h, w), config.background_counts, dtype=np.float32)
    m = config.noise_pool_margin_px
    pool = _noise_pool(
        h, w, config.background_counts, config.noise_sigma_counts, config.noise_pool_frames, m
    )
    k, dy, dx = (int(v) for v in rng.integers(0, [len(pool), m + 1, m + 1]))
    return pool[k, dy : dy + h, dx : dx + w].copy()


def _add_patch(
    frame: npt.NDArray[np.float32] | ImageU8, r0: int, c0: int, patch: FloatArray
) -> None:
    """Add counts to a float frame, or to a uint8 frame with rounding and saturation."""
    rows, cols = slice(r0, r0 + patch.shape[0]), slice(c0, c0 + patch.shape[1])
    if frame.dtype == np.uint8:
        total = frame[rows, cols] + patch + 0.5
        frame[rows, cols] = np.clip(total, 0.0, 255.0).astype(np.uint8)
    else:
        frame[rows, cols] += patch.astype(np.float32)


def _camera_points(
    camera: CameraModel, T_world_body: FloatArray, p_world: FloatArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Camera-frame points, their pixels and which are visible in the image."""
    p_camera = transform_points(T_camera_world(camera, T_world_body), p_world)
    pixels, valid = pixels_from_points_camera(camera, p_camera)
    return p_camera, pixels, valid


def spot_fluxes(p_camera: FloatArray, intensities: FloatArray, config: RenderConfig) -> FloatArray:
    """Total counts of each point source's spot (distance and angle fall-off).

    Args:
        p_camera: source positions in the camera frame, metres, shape (N, 3).
        intensities: 1.0 = a nominal landmark LED, shape (N,).

    Returns:
        shape (N,), counts.
    """
    d = np.linalg.norm(p_camera, axis=1)
    cos_a = np.clip(p_camera[:, 2] / np.maximum(d, 1e-9), 0.0, 1.0)
    scale = (config.nominal_distance_m / np.maximum(d, 1e-6)) ** 2
    flux: FloatArray = (
        config.nominal_flux_counts * intensities * scale * cos_a**config.falloff_exponent
    )
    return flux


def add_spots(
    frame: npt.NDArray[np.float32] | ImageU8,
    centers: FloatArray,
    fluxes: FloatArray,
    config: RenderConfig,
) -> None:
    """Add pixel-integrated Gaussian spots to a frame in place, all in one vectorised pass.

    Each pixel receives flux * (the Gaussian's integral over the pixel's square), computed
    with `erf` per row and column. Every spot gets the same square patch, sized for the
    brightest one (out to where it falls below `min_spot_counts`). Overlapping spots add up.

    Args:
        frame: float32 counts or uint8 (H, W) (then rounded and saturated per pixel).
        centers: spot centres (col, row), shape (N, 2).
        fluxes: total counts of each spot, shape (N,).
    """
    if not frame.flags.c_contiguous:
        raise ValueError("add_spots: the frame must be a C-contiguous array")
    sigma = config.psf_sigma_px
    keep = fluxes / (2.0 * math.pi * sigma * sigma) > config.min_spot_counts
    if not np.any(keep):
        return
    c, f = np.asarray(centers, dtype=np.float64)[keep], np.asarray(fluxes, dtype=np.float64)[keep]
    peak = float(f.max()) / (2.0 * math.pi * sigma * sigma)
    radius = sigma * math.sqrt(2.0 * math.log(peak / config.min_spot_counts))
    r = min(math.ceil(radius) + 1, config.max_spot_radius_px)
    offsets = np.arange(-r, r + 1)
    cols = np.rint(c[:, 0]).astype(np.int64)[:, None] + offsets  # (N, P)
    rows = np.rint(c[:, 1]).astype(np.int64)[:, None] + offsets
    s = sigma * math.sqrt(2.0)
    edges = np.arange(-r, r + 2) - 0.5
    ex = erf((np.rint(c[:, 0])[:, None] + edges - c[:, 0:1]) / s)
    ey = erf((np.rint(c[:, 1])[:, None] + edges - c[:, 1:2]) / s)
    gx, gy = 0.5 * np.diff(ex, axis=1), 0.5 * np.diff(ey, axis=1)
    values = f[:, None, None] * gy[:, :, None] * gx[:, None, :]  # (N, P, P)
    h, w = frame.shape
    inside = ((rows >= 0) & (rows < h))[:, :, None] & ((cols >= 0) & (cols < w))[:, None, :]
    index = rows[:, :, None] * w + cols[:, None, :]
    pixels, where = np.unique(index[inside], return_inverse=True)
    sums = np.bincount(where, weights=values[inside])
    flat = frame.reshape(-1)
    if frame.dtype == np.uint8:
        flat[pixels] = np.clip(flat[pixels] + sums + 0.5, 0.0, 255.0).astype(np.uint8)
    else:
        flat[pixels] += sums.astype(np.float32)


def render_extended(
    frame: npt.NDArray[np.float32] | ImageU8,
    camera: CameraModel,
    T_world_body: FloatArray,
    source: ExtendedSource,
    config: RenderConfig,
) -> None:
    """Add an extended source (a filled, soft-edged outline) to a frame in place.

    The outline's corners in front of the camera and within the lens's field of view are
    projected and filled; the brightness falls with the angle of the outline's centre from the
    optical axis like a point source's.

    Args:
        frame: float32 counts or uint8 (H, W), modified in place.
        T_world_body: body pose, shape (4, 4).
        source: the outline and its brightness.
    """
    pts = source.outline_world
    p_camera = transform_points(T_camera_world(camera, T_world_body), pts)
    norm = np.linalg.norm(p_camera, axis=1)
    cos_a = p_camera[:, 2] / np.maximum(norm, 1e-9)
    in_view = (p_camera[:, 2] > 1e-6) & (np.arccos(np.clip(cos_a, -1, 1)) <= camera.max_angle_rad)
    if np.count_nonzero(in_view) < 3:
        return
    pixels, _ = pixels_from_points_camera(camera, p_camera[in_view])
    centre = p_camera[in_view].mean(axis=0)
    level = (
        source.brightness_counts
        * (max(centre[2], 0.0) / max(float(np.linalg.norm(centre)), 1e-9))
        ** config.falloff_exponent
    )
    h, w = frame.shape
    pad = math.ceil(3 * config.extended_edge_sigma_px) + 1
    lo = np.floor(pixels.min(axis=0)).astype(int) - pad
    hi = np.ceil(pixels.max(axis=0)).astype(int) + pad
    c0, r0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    c1, r1 = min(int(hi[0]), w - 1), min(int(hi[1]), h - 1)
    if c0 > c1 or r0 > r1:
        return
    shift = 4  # cv2 fixed-point bits: sub-pixel outline corners
    mask = np.zeros((r1 - r0 + 1, c1 - c0 + 1), dtype=np.float32)
    corners = np.round((pixels - [c0, r0]) * (1 << shift)).astype(np.int32)
    cv2.fillPoly(mask, [corners.reshape(-1, 1, 2)], 1.0, lineType=cv2.LINE_AA, shift=shift)
    if config.extended_edge_sigma_px > 0:
        mask = cv2.GaussianBlur(mask, (0, 0), config.extended_edge_sigma_px)
    _add_patch(frame, r0, c0, level * mask.astype(np.float64))


def to_uint8(frame: npt.NDArray[np.float32], config: RenderConfig) -> ImageU8:
    """Round, clip at 0 and saturation, and convert a float frame to 8 bit."""
    np.add(frame, np.float32(0.5), out=frame)
    np.clip(frame, 0.0, min(config.saturation_counts, 255.0), out=frame)
    return frame.astype(np.uint8)


def render_frame(
    camera: CameraModel,
    T_world_body: FloatArray,
    sources_world: npt.ArrayLike,
    intensities: npt.ArrayLike,
    *,
    rng: np.random.Generator | None,
    config: RenderConfig | None = None,
    extended: Sequence[ExtendedSource] = (),
) -> ImageU8:
    """Render the 8-bit frame the camera sees from a body pose.

    Args:
        camera: the true camera (lens and mounting).
        T_world_body: body pose, shape (4, 4) (a tilted body is allowed).
        sources_world: point sources (lit LEDs, glints), metres, shape (N, 3).
        intensities: 1.0 = a nominal landmark LED seen on the optical axis at
            `config.nominal_distance_m`; 0 = dark, shape (N,).
        rng: picks the read-noise frame; None renders without noise.
        config: optics and sensor; defaults to `RenderConfig()`.
        extended: extended sources drawn under the point sources.

    Returns:
        uint8 image, shape (height, width).
    """
    cfg = config or RenderConfig()
    frame = _dark_frame(camera, rng, cfg)
    for source in extended:
        render_extended(frame, camera, T_world_body, source, cfg)
    p_world = np.asarray(sources_world, dtype=np.float64).reshape(-1, 3)
    inten = np.asarray(intensities, dtype=np.float64).reshape(-1)
    if len(inten) != len(p_world):
        raise ValueError(f"render_frame: {len(p_world)} sources but {len(inten)} intensities")
    lit = inten > 0
    if np.any(lit):
        p_camera, pixels, valid = _camera_points(camera, T_world_body, p_world[lit])
        fluxes = spot_fluxes(p_camera, inten[lit], cfg)
        add_spots(frame, pixels[valid], fluxes[valid], cfg)
    if frame.dtype == np.uint8:
        image: ImageU8 = frame.astype(np.uint8, copy=False)
        if cfg.saturation_counts < 255:
            np.minimum(image, np.uint8(cfg.saturation_counts), out=image)
        return image
    return to_uint8(frame.astype(np.float32, copy=False), cfg)
