"""Camera placements of the viewer: the top view (the default), an oblique view, following
a robot.

viser 1.1 has no orthographic camera: the top view is a telephoto view from far above
(`TopView.fov_deg` wide), which is near-orthographic: seen from `distance` metres, the
ceiling at 2.5 m is drawn 2.5 / distance larger than the floor (about 1.5 % for the demo
site), so a landmark straight above a robot is drawn on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from web.footprint import Bounds


class CameraLike(Protocol):
    """viser's `server.initial_camera` or a client's `client.camera`."""

    position: tuple[float, float, float] | np.ndarray
    look_at: tuple[float, float, float] | np.ndarray
    fov: float
    near: float
    far: float


@dataclass(frozen=True)
class TopView:
    """The top view.

    Attributes:
        fov_deg: vertical field of view, degrees (narrow: near-orthographic).
        screen_aspect: width/height of the browser window (16:10 is common).
        panel_share: share of the window's width the GUI panel covers at the right; the
            site is fitted into the rest and centred there.
        margin: share of the site's extent left free around it.
        near_m: near clipping distance, metres (far from the camera: depth precision).
    """

    fov_deg: float = 6.0
    screen_aspect: float = 1.6
    panel_share: float = 0.25
    margin: float = 0.06
    near_m: float = 1.0

    def distance(self, bounds: Bounds) -> float:
        """Height above the floor at which the site fills the free part of the view, m."""
        x0, x1, y0, y1 = bounds
        free_aspect = self.screen_aspect * (1.0 - self.panel_share)
        half = max((y1 - y0) / 2.0, (x1 - x0) / (2.0 * free_aspect)) * (1.0 + self.margin)
        return max(half, 1.0) / math.tan(math.radians(self.fov_deg) / 2.0)

    def panel_shift_m(self, distance: float) -> float:
        """How far east of the site's centre to look so that the site is centred in the
        part of the window the panel leaves free, metres."""
        visible_w = 2.0 * distance * math.tan(math.radians(self.fov_deg) / 2.0)
        return 0.5 * self.panel_share * visible_w * self.screen_aspect


INITIAL_TOP_VIEW = TopView(screen_aspect=390 / 844, panel_share=0.0)
"""The top view every browser starts from, until the one fitted to its own window
(`ViewPanel.fit_window`) lands, and if viser's initial camera reaches the browser after
that one: the whole site in any window, a portrait phone's included (a desktop sees it
smaller, centred clear of the panel)."""

OBLIQUE_FOV_DEG = 60.0


def _set_up(camera: object, up: tuple[float, float, float]) -> None:
    if hasattr(camera, "up_direction"):
        camera.up_direction = up
    else:
        camera.up = up  # type: ignore[attr-defined]  # viser's InitialCameraConfig


def apply_top_view(
    camera: CameraLike, bounds: Bounds, view: TopView | None = None
) -> tuple[float, float, float]:
    """Look straight down on the site from far above; returns the look-at point.

    The camera sits a hair south of the vertical so that north (+y) is up on the screen.
    """
    v = view or TopView()
    x0, x1, y0, y1 = bounds
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    d = v.distance(bounds)
    cx += v.panel_shift_m(d)
    camera.fov = math.radians(v.fov_deg)
    camera.near, camera.far = v.near_m, 4.0 * d
    camera.position = (cx, cy - 1e-3 * d, d)  # position first: viser's setter moves look_at
    camera.look_at = (cx, cy, 0.0)
    _set_up(camera, (0.0, 0.0, 1.0))
    return (cx, cy, 0.0)


def apply_oblique_view(
    camera: CameraLike, bounds: Bounds, ceiling_z: float
) -> tuple[float, float, float]:
    """From the south-west, below the ceiling's far side; returns the look-at point."""
    x0, x1, y0, y1 = bounds
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    span = max(x1 - x0, y1 - y0, 1.0)
    camera.fov = math.radians(OBLIQUE_FOV_DEG)
    camera.near, camera.far = 0.05, 1000.0
    camera.position = (cx - 0.2 * span, cy - 0.75 * span, ceiling_z + 0.3 * span)
    camera.look_at = (cx, cy, 0.8)
    _set_up(camera, (0.0, 0.0, 1.0))
    return (cx, cy, 0.8)


def follow(camera: CameraLike, look_at: np.ndarray, target_xy: tuple[float, float]) -> np.ndarray:
    """Move the camera with a robot: the same shift for the camera and its look-at point
    (viser's position setter moves both), which lands on the robot; returns the new
    look-at point."""
    new = np.array([target_xy[0], target_xy[1], float(look_at[2])])
    shift = new - np.asarray(look_at, dtype=np.float64)
    if float(np.abs(shift).max()) < 1e-3:
        return np.asarray(look_at, dtype=np.float64)
    camera.position = tuple(np.asarray(camera.position, dtype=np.float64) + shift)
    return new
