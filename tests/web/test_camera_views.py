"""Camera placements: the near-orthographic top view and following a robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

from web.camera_views import (
    INITIAL_TOP_VIEW,
    TopView,
    apply_oblique_view,
    apply_top_view,
    follow,
)


class Camera:
    """What viser's camera handles hold (a client's moves its look-at with its position)."""

    def __init__(self) -> None:
        self.position = np.zeros(3)
        self.look_at = np.array([0.0, 0.0, -1.0])
        self.up_direction = (0.0, 0.0, 1.0)
        self.fov, self.near, self.far = 1.3, 0.01, 1000.0

    def __setattr__(self, name: str, value: object) -> None:
        if name == "position" and "position" in self.__dict__:
            shift = np.asarray(value, dtype=float) - self.__dict__["position"]
            self.__dict__["look_at"] = self.__dict__["look_at"] + shift
        self.__dict__[name] = (
            np.asarray(value, dtype=float) if name in ("position", "look_at") else value
        )


def test_top_view_fits_the_site_beside_the_panel_nearly_without_parallax() -> None:
    bounds = (-2.0, 16.5, -2.0, 9.5)
    cam, view = Camera(), TopView()
    look = apply_top_view(cam, bounds)  # type: ignore[arg-type]
    d = float(cam.position[2])
    half_h = d * math.tan(math.radians(view.fov_deg) / 2)
    free_w = 2 * half_h * view.screen_aspect * (1 - view.panel_share)
    assert free_w >= 18.5 and 2 * half_h >= 11.5  # the whole site is in the free part
    assert 2.5 / (d - 2.5) < 0.02  # ceiling vs floor scale: under 2 %
    np.testing.assert_allclose(cam.look_at, look)
    assert look[0] > 7.25  # looked east of the centre: the panel covers the right
    assert cam.near >= 1.0 and cam.far > d
    apply_oblique_view(cam, bounds, 2.5)  # type: ignore[arg-type]
    assert cam.fov == pytest.approx(math.radians(60.0)) and cam.near < 0.1


@pytest.mark.parametrize("aspect", [390 / 844, 1.0, 1.6, 2.4])
def test_the_initial_view_shows_the_whole_site_in_any_window(aspect: float) -> None:
    """Before (or instead of) the view fitted to a browser's window: a portrait phone and a
    wide screen alike see the whole site, centred (a desktop's panel at the right covers
    none of it)."""
    bounds = (-2.0, 26.0, -2.0, 9.5)
    cam = Camera()
    look = apply_top_view(cam, bounds, INITIAL_TOP_VIEW)  # type: ignore[arg-type]
    assert look[:2] == pytest.approx((12.0, 3.75))
    half_h = float(cam.position[2]) * math.tan(math.radians(INITIAL_TOP_VIEW.fov_deg) / 2)
    half_w = half_h * aspect
    assert half_w >= 14.0 and half_h >= 5.75  # the site's half extents
    if aspect >= 1.6:  # clear of a quarter-width panel at the right
        assert look[0] + 14.0 <= look[0] + half_w * (1 - 2 * 0.25)


def test_following_moves_camera_and_look_at_together_onto_the_robot() -> None:
    cam = Camera()
    apply_top_view(cam, (0.0, 10.0, 0.0, 10.0))  # type: ignore[arg-type]
    offset = cam.position - cam.look_at
    follow(cam, cam.look_at, (3.0, 4.0))  # type: ignore[arg-type]
    np.testing.assert_allclose(cam.look_at[:2], [3.0, 4.0])
    np.testing.assert_allclose(cam.position - cam.look_at, offset)  # same view, moved
