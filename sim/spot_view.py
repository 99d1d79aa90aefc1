"""Spot-level camera: what a frame's spot detection would return, without rendering it.

For long simulated shifts (`bench/bench_battery.py`) rendering every frame is too slow, so
the camera reports the point sources' spots directly: each lit landmark or glint projected
through the robot's *true* camera (calibration error included), kept when its peak clears
the detection contrast, its centroid jittered by the centroid noise of a real detection.
Extended sources (lamps, sunlight) are left out: at spot level they are no point source.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel, T_camera_world, pixels_from_points_camera
from localizer.events import SpotsObserved
from localizer.geometry import transform_points
from localizer.types import FloatArray
from sim.render import RenderConfig, spot_fluxes
from sim.world import World


def observe_spots(
    world: World,
    camera: CameraModel,
    T_world_body: FloatArray,
    t_ns: int,
    rng: np.random.Generator,
    config: RenderConfig,
    *,
    led_t_ns: int | None = None,
    min_peak_counts: float = 12.0,
    centroid_sigma_px: float = 0.08,
    floor: str | None = None,
) -> SpotsObserved:
    """The spots a frame taken at `t_ns` from body pose `T_world_body` (4, 4) would show.

    Args:
        led_t_ns: take the LEDs as they were at this world time (None: as they are now).
        min_peak_counts: a spot whose peak pixel is fainter than this above the background
            is not detected (the detector's minimum contrast), counts.
        centroid_sigma_px: standard deviation of a detected centroid per axis, pixels.
        floor: the robot's floor (`World.point_sources`); None: every landmark.
    """
    T_wc = T_world_body @ camera.T_body_camera
    sources, intensities = world.point_sources(T_wc[:3, 3], t_ns=led_t_ns, floor=floor)
    empty = np.zeros((0, 2))
    if len(sources) == 0:
        return SpotsObserved(t_ns, empty, np.zeros(0), np.zeros(0))
    p_cam = transform_points(T_camera_world(camera, T_world_body), sources)
    px, valid = pixels_from_points_camera(camera, p_cam)
    flux = spot_fluxes(p_cam, intensities, config)
    peak = flux / (2.0 * math.pi * config.psf_sigma_px**2)
    inside = (
        valid
        & (px[:, 0] >= 0)
        & (px[:, 0] <= camera.width - 1)
        & (px[:, 1] >= 0)
        & (px[:, 1] <= camera.height - 1)
        & (peak >= min_peak_counts)
    )
    px = px[inside] + rng.normal(0.0, centroid_sigma_px, (int(inside.sum()), 2))
    flux = flux[inside]
    areas = np.clip(np.round(flux / np.maximum(peak[inside], 1e-9) / 2.0), 2.0, 60.0)
    return SpotsObserved(t_ns, px, flux, areas)
