"""The operator's screen in a real browser (Debian's Chromium, headless, Playwright) on the
live demo site: what is drawn is checked by the pixels of the page, not by the messages
sent to it (the uncertainty curve once reached the page as 600 points and drew nothing)."""

from __future__ import annotations

import io
import re
import time
from typing import Any

import numpy as np
import pytest

from tests.web.conftest import ServedSite
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
    live_site: ServedSite,
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


def _open_at(ctx: Any, site: ServedSite, width: int, height: int) -> Any:
    page = ctx.new_page()
    page.set_default_timeout(90_000)
    page.set_viewport_size({"width": width, "height": height})
    page.goto(f"{site.base}/viewer/?token={site.operator_key}")
    page.wait_for_function("() => Object.keys((window.__viserMutable || {}).nodeRefFromName"
                           " || {}).some(k => k.startsWith('/landmarks/'))")  # fmt: skip
    page.get_by_text("Connecting...").wait_for(state="hidden", timeout=60_000)
    page.get_by_text("signed in as operator").wait_for(timeout=30_000)
    return page


def _trails_in_view(page: Any, names: list[str], height: int) -> dict[str, int]:
    """Each robot's trail pixels above the folded panel, once all are in view (the whole
    hall is) or after 60 s."""
    deadline = time.monotonic() + 60
    trails: dict[str, int] = {}
    while time.monotonic() < deadline:
        wait_frames(page, 3)
        img = rgb_of(page.screenshot())[: int(0.8 * height)]
        trails = {n: pixels_of_hue(img, robot_color(i)) for i, n in enumerate(names)}
        if min(trails.values()) > 30:
            break
        time.sleep(1.0)
    return trails


@pytest.mark.timeout(600)
def test_a_phone_whose_size_comes_late_still_gets_the_whole_hall(
    browser: Any,  # noqa: F811
    live_site: ServedSite,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The page's size is not known yet when its panels are built (its first camera message
    came after the viewer's wait, as on a loaded machine): the top view is fitted to the
    phone when the size comes (here with the next camera message, on a resize)."""
    import web.client_panels

    monkeypatch.setattr(web.client_panels, "wait_for_width", lambda client, timeout_s: 0)
    names = list(live_site.services.robots.names())
    page = _open_at(browser, live_site, 390, 844)
    try:
        page.set_viewport_size({"width": 390, "height": 840})  # a camera message, with its size
        trails = _trails_in_view(page, names, 840)
        assert min(trails.values()) > 30, f"trails in view on a phone: {trails}"
    finally:
        page.close()


@pytest.mark.timeout(600)  # two pages, software WebGL on a loaded machine
def test_phone_shows_the_hall_and_a_wide_screen_a_wide_panel(
    browser: Any,  # noqa: F811
    live_site: ServedSite,
) -> None:
    """At 390x844 the panels start folded and the whole hall is in view (the panel once
    covered it); at 1920x1080 the panel is wide enough for the tables (it stayed 240 px and
    wrapped). Screenshots of both sizes for the docs (the desktop size's is
    `test_zones_click_to_inspect_and_history_playback`'s first)."""
    names = list(live_site.services.robots.names())
    page = _open_at(browser, live_site, 390, 844)
    try:
        trails = _trails_in_view(page, names, 844)
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


def screen_xy(page: Any, node: str) -> tuple[float, float]:
    """Where a scene node's origin is drawn on the page, CSS pixels (three.js projection
    with the page's camera)."""
    xy: list[float] = page.evaluate(
        """name => { const m = window.__viserMutable; const o = m.nodeRefFromName[name];
        const v = o.position.clone(); o.parent.localToWorld(v); v.project(m.camera);
        const r = document.querySelector('canvas').getBoundingClientRect();
        return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height]; }""",
        node,
    )
    return xy[0], xy[1]


@pytest.mark.timeout(300)
def test_zones_click_to_inspect_and_history_playback(
    browser: Any,  # noqa: F811
    live_site: ServedSite,
) -> None:
    """A zone made through the API is drawn on the floor in its colour; a landmark clicked in
    the view is described in the Selected panel, and Cells replaced (ticked) starts its
    battery estimate over; the history folder draws a robot's trail, its ghost and the
    heatmap from the kept poses. The zone is made once the page shows the site (a zone made
    while a browser watches is drawn in it); before, the page is the docs' desktop picture."""
    from web.zones_view import ZONE_COLOR

    services = live_site.services
    lms = services.map.list()
    xs, ys = [lm.x for lm in lms], [lm.y for lm in lms]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
    page = _open_at(browser, live_site, 1280, 800)
    try:
        wait_frames(page, 5)
        save_shot(page, "viewer-desktop.png", doc=True)
        services.zones.create("loading bay", [(x0, y0), (xm, y0), (xm, ym), (x0, ym)])
        page.wait_for_function("() => Object.keys(window.__viserMutable.nodeRefFromName)"
                               ".some(k => k.startsWith('/zones/'))", timeout=30_000)  # fmt: skip
        page.get_by_text("loading bay").first.wait_for(timeout=30_000)  # its label
        wait_frames(page, 3)
        canvas = page.locator("canvas").first
        assert pixels_of_hue(rgb_of(canvas.screenshot()), ZONE_COLOR) > 200
        target = min(lms, key=lambda lm: np.hypot(lm.x - x1, lm.y - y1))  # away from robots
        x, y = screen_xy(page, f"/landmarks/{target.id}")
        page.mouse.click(x, y)
        page.get_by_text(f"Landmark {target.id}").first.wait_for(timeout=30_000)
        page.get_by_role("button", name="Cells replaced").wait_for(timeout=10_000)
        wait_frames(page, 3)
        save_shot(page, "viewer-inspect.png", doc=True)
        page.get_by_label("Yes, its cells are new").check()
        page.get_by_role("button", name="Cells replaced").click()
        note = page.get_by_text("battery estimate starts over").first
        note.wait_for(timeout=60_000)
        # the virtual landmark got its fresh cells: the supply read at once is a new pair's
        assert re.search(r"reads 3\.\d\d V", note.inner_text()), note.inner_text()
        assert services.log.last_event("cells_replaced", landmark_id=target.id) is not None
        page.get_by_text("History playback").first.click()
        page.get_by_label("Heatmap of every robot").check()
        page.get_by_role("button", name="Show history").click()
        page.wait_for_function("() => ['/playback/trail', '/playback/ghost', '/playback/heatmap']"
                               ".every(k => !!window.__viserMutable.nodeRefFromName[k])",
                               timeout=30_000)  # fmt: skip
        summary = page.get_by_text("heatmap:").first
        summary.wait_for(timeout=10_000)
        summary.scroll_into_view_if_needed()
        wait_frames(page, 5)
        save_shot(page, "viewer-history.png", doc=True)
    finally:
        page.close()
