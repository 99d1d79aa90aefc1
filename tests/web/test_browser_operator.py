"""The operator's screen in a real browser (Debian's Chromium, headless, Playwright) on the
live demo site: what is drawn is checked by the pixels of the page, not by the messages
sent to it (the uncertainty curve once reached the page as 600 points and drew nothing)."""

from __future__ import annotations

import io
import time
from typing import Any

import numpy as np
import pytest

from tests.web.conftest import LiveSite
from tests.web.test_browser import (  # noqa: F401  (the module's browser fixture)
    CHROMIUM,
    browser,
    open_viewer,
    save_shot,
    wait_frames,
)
from web.colors import robot_color

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.skipif(not CHROMIUM.exists(), reason="no /usr/bin/chromium"),
]
SERIES_RGB = (0x22, 0xAA, 0x77)  # the uncertainty plot's stroke, "#2a7"


def rgb_of(png: bytes) -> np.ndarray:
    """A screenshot's pixels, shape (H, W, 3), uint8."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def pixels_of_hue(img: np.ndarray, rgb: tuple[int, int, int], tol_deg: float = 18.0) -> int:
    """How many clearly coloured pixels (saturation >= 0.25) have the hue of `rgb` within
    `tol_deg` (the scene's tone mapping lightens colours and shifts hues a little)."""
    return int(np.count_nonzero(hue_mask(img, rgb, tol_deg)))


def hue_mask(img: np.ndarray, rgb: tuple[int, int, int], tol_deg: float = 18.0) -> np.ndarray:
    """Where `pixels_of_hue` counts, shape (H, W), bool."""
    import colorsys

    import cv2

    hsv = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2HSV_FULL).astype(np.float64)
    want = 360.0 * colorsys.rgb_to_hsv(*(c / 255.0 for c in rgb))[0]
    off = np.abs((hsv[..., 0] * 360.0 / 256.0 - want + 180.0) % 360.0 - 180.0)
    return (off <= tol_deg) & (hsv[..., 1] >= 64) & (hsv[..., 2] >= 96)


def pixels_near(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 24) -> int:
    """How many pixels are within `tol` of `rgb` in every channel."""
    d = np.abs(img.astype(np.int16) - np.array(rgb, dtype=np.int16))
    return int(np.count_nonzero(np.all(d <= tol, axis=-1)))


def test_uncertainty_curve_trails_in_each_robots_colour_and_no_share_button(
    browser: Any,  # noqa: F811
    live_site: LiveSite,
) -> None:
    page = open_viewer(browser, live_site, live_site.viewer_key)
    try:
        page.get_by_text("signed in as viewer").wait_for(timeout=20_000)
        # viser's Share button (a public tunnel to viser's unkeyed port) is not there
        assert page.locator("svg.tabler-icon-share").count() == 0
        plot = page.locator(".uplot canvas").first
        plot.scroll_into_view_if_needed()
        deadline = time.monotonic() + 60
        curve = 0
        while time.monotonic() < deadline:  # the panel refreshes at 2 Hz
            curve = pixels_near(rgb_of(plot.screenshot()), SERIES_RGB)
            if curve > 150:
                break
            time.sleep(1.0)
        assert curve > 150, f"the uncertainty curve drew {curve} pixels of its colour"
        # every robot's trail in its own colour, on the 3D view
        names = list(live_site.services.robots.names())
        canvas = page.locator("canvas").first
        counts: dict[str, int] = {}
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            wait_frames(page, 3)
            img = rgb_of(canvas.screenshot())
            counts = {n: pixels_of_hue(img, robot_color(i)) for i, n in enumerate(names)}
            if min(counts.values()) > 40:
                break
            time.sleep(2.0)
        save_shot(page, "viewer-trails.png")
        assert min(counts.values()) > 40, counts
    finally:
        page.close()


def _open_at(ctx: Any, site: LiveSite, width: int, height: int) -> Any:
    page = ctx.new_page()
    page.set_default_timeout(90_000)
    page.set_viewport_size({"width": width, "height": height})
    page.goto(f"{site.base}/viewer/?token={site.operator_key}")
    page.wait_for_function("() => Object.keys((window.__viserMutable || {}).nodeRefFromName"
                           " || {}).some(k => k.startsWith('/landmarks/'))")  # fmt: skip
    page.get_by_text("Connecting...").wait_for(state="hidden", timeout=60_000)
    page.get_by_text("signed in as operator").wait_for(timeout=30_000)
    return page


@pytest.mark.timeout(600)  # three pages, software WebGL on a loaded machine
def test_phone_shows_the_hall_and_a_wide_screen_a_wide_panel(
    browser: Any,  # noqa: F811
    live_site: LiveSite,
) -> None:
    """At 390x844 the panels start folded and the whole hall is in view (the panel once
    covered it); at 1920x1080 the panel is wide enough for the tables (it stayed 240 px and
    wrapped). Screenshots of the three sizes for the docs."""
    names = list(live_site.services.robots.names())
    page = _open_at(browser, live_site, 390, 844)
    try:
        deadline = time.monotonic() + 60
        trails: dict[str, int] = {}  # every robot's trail in view: the whole hall is
        while time.monotonic() < deadline:
            wait_frames(page, 3)
            img = rgb_of(page.screenshot())[: int(0.8 * 844)]  # above the folded panel
            trails = {n: pixels_of_hue(img, robot_color(i)) for i, n in enumerate(names)}
            if min(trails.values()) > 30:
                break
            time.sleep(1.0)
        save_shot(page, "viewer-phone.png", doc=True)
        assert min(trails.values()) > 30, f"trails in view on a phone: {trails}"
    finally:
        page.close()
    page = _open_at(browser, live_site, 1920, 1080)
    try:
        table = page.locator("table").first
        deadline = time.monotonic() + 30
        width = 0.0
        while time.monotonic() < deadline:
            box = table.bounding_box()
            width = 0.0 if box is None else box["width"]
            if width >= 340:
                break
            time.sleep(0.5)
        wait_frames(page, 5)
        save_shot(page, "viewer-wide.png", doc=True)
        assert width >= 340, f"the robots table is {width} px wide at 1920x1080"
    finally:
        page.close()
    page = _open_at(browser, live_site, 1280, 800)
    try:
        wait_frames(page, 5)
        save_shot(page, "viewer-desktop.png", doc=True)
    finally:
        page.close()
