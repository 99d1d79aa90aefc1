"""The viewer in a real browser: Debian's Chromium, headless, driven by Playwright, against
the app with the `demo` virtual site (`live_site`). Software WebGL costs most of a core: the
tests are few, share one browser and keep their waits generous."""

from __future__ import annotations

import os
import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.web.conftest import ARTIFACTS, DOC_IMAGES, LiveSite

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]  # fmt: skip
LANDMARKS_IN_SCENE = (  # a JS expression: the number of /landmarks/<id> scene nodes
    "Object.keys((window.__viserMutable || {}).nodeRefFromName || {})"
    ".filter(k => /^\\/landmarks\\/\\d+$/.test(k)).length"
)

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.skipif(
        not CHROMIUM.exists(),
        reason="no /usr/bin/chromium: install Debian's chromium (apt-get install chromium) "
        "to run the browser tests",
    ),
]


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium")), executable_path=str(CHROMIUM),
            headless=True, args=ARGS, viewport={"width": 1280, "height": 800},
        )  # fmt: skip
        try:
            yield ctx
        finally:
            ctx.close()


def open_viewer(browser: Any, site: LiveSite, key: str) -> Any:
    page = browser.new_page()
    page.set_default_timeout(90_000)  # software WebGL on a busy 2-core machine
    page.goto(f"{site.base}/viewer/?token={key}")
    page.wait_for_function(f"() => {LANDMARKS_IN_SCENE} > 0", timeout=90_000)
    page.get_by_text("Connecting...").wait_for(state="hidden", timeout=60_000)
    return page


def dismiss_software_webgl_notice(page: Any) -> None:
    """Close viser's "Software WebGL rendering detected" notice (headless Chromium has no
    GPU; a staff member's browser does not show it)."""
    notice = page.locator(".mantine-Notification-root", has_text="Software WebGL")
    if notice.count():
        notice.first.locator("button").first.click()
        notice.first.wait_for(state="hidden", timeout=10_000)


def save_shot(page: Any, name: str, *, doc: bool = False) -> None:
    if doc:
        dismiss_software_webgl_notice(page)
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / name
    page.screenshot(path=str(path))
    if doc and os.environ.get("IRLOC_UPDATE_DOC_IMAGES") == "1":  # README pictures, on request
        DOC_IMAGES.mkdir(parents=True, exist_ok=True)
        shutil.copy(path, DOC_IMAGES / name)


def test_scene_renders_with_every_landmark_of_the_map(browser: Any, live_site: LiveSite) -> None:
    page = open_viewer(browser, live_site, live_site.admin_key)
    try:
        n_map = len(live_site.services.map.list())
        page.wait_for_function(f"() => {LANDMARKS_IN_SCENE} === {n_map}", timeout=30_000)
        assert page.evaluate(f"() => {LANDMARKS_IN_SCENE}") == n_map
        for name in live_site.services.robots.names():
            page.wait_for_function(
                f"() => !!window.__viserMutable.nodeRefFromName['/robots/{name}/position/body']",
                timeout=30_000,
            )
        page.get_by_text("signed in as admin").wait_for(timeout=10_000)
        time.sleep(3.0)  # let software WebGL draw a few frames
        save_shot(page, "viewer-monitoring.png", doc=True)
    finally:
        page.close()


def test_viewer_key_sees_but_cannot_edit(browser: Any, live_site: LiveSite) -> None:
    page = open_viewer(browser, live_site, live_site.viewer_key)
    try:
        page.get_by_text("signed in as viewer").wait_for(timeout=20_000)
        assert page.get_by_text("Commission", exact=True).count() == 0
        for name in ("Relocalize", "Add landmark", "Start identification", "Undo last change"):
            assert page.get_by_role("button", name=name).count() == 0, name
        assert page.evaluate(f"() => {LANDMARKS_IN_SCENE}") == len(live_site.services.map.list())
    finally:
        page.close()


def test_wizard_keeps_the_fleet_tracking_and_a_far_measurement_needs_accept_far(
    browser: Any, live_site: LiveSite
) -> None:
    """Through the browser's buttons, on the live site: the landmark's map position is 4.2 m
    off; the wizard darkens it alone against the lit ceiling, the other robots stay in
    landmark mode on >= 95 % of their frames, the far measurement is flagged and Confirm
    stays disabled until "Accept far" is ticked; the saved position is the true one (the
    simulator's truth only checks it)."""
    from server.models import LandmarkUpdate
    from tests.web.conftest import landmark_always_in_view, wait_localized

    services = live_site.services
    world = services.sim.world
    viewer = live_site.app.state.viewer
    robot = "r2"
    page = open_viewer(browser, live_site, live_site.admin_key)
    sub = services.robots.subscribe_poses(maxsize=100_000)
    try:
        page.get_by_role("tab", name="Commission").click()
        page.get_by_label("Camera of").click()  # a Mantine select: open it, pick the option
        page.get_by_role("option", name=robot, exact=True).click()
        lid = landmark_always_in_view(services, robot)
        truth = np.array(world.landmarks[lid].p_true)
        far = LandmarkUpdate(x=float(truth[0]) + 3.0, y=float(truth[1]) + 3.0)
        services.map.update(lid, far, actor="test")
        # viser's text input's label does not point at it (its `for` is another id)
        ids = page.locator("xpath=//label[normalize-space()='Landmark IDs']/following::input[1]")
        ids.fill(str(lid))
        ids.press("Enter")
        time.sleep(1.0)
        wait_localized(viewer.site, robot, services)
        confirm = page.get_by_role("button", name="Confirm position")
        assert confirm.is_disabled()  # nothing measured
        sub.drain()
        page.get_by_role("button", name="Start identification").click()
        page.get_by_text(re.compile("Far from the map")).wait_for(timeout=90_000)
        st = services.commissioning.status()
        assert st.measurement is not None and st.measurement.plausibility.far, st
        assert st.phase == "measuring" and not st.can_confirm
        assert world.lit_ids() >= set(services.map.addresses()) - {lid}  # never the ceiling
        time.sleep(2.0)
        save_shot(page, "viewer-commissioning.png", doc=True)
        assert confirm.is_disabled()  # cannot be confirmed by accident
        confirm.click(force=True)  # a click on the disabled button does nothing
        time.sleep(1.0)
        assert services.map.get(lid).x == pytest.approx(far.x)
        poses = sub.drain()
        for other in ("r1", "r3"):
            modes = [p.mode for p in poses if p.robot == other]
            share = modes.count("landmark") / max(1, len(modes))
            assert len(modes) > 30 and share >= 0.95, (other, share, len(modes))
        page.get_by_text("Accept far", exact=True).click()
        page.wait_for_function(
            "() => [...document.querySelectorAll('button')].some(b => "
            "b.textContent.trim() === 'Confirm position' && !b.disabled)",
            timeout=30_000,
        )
        confirm.click()
        page.get_by_text(re.compile(r"done: saved")).wait_for(timeout=60_000)
        saved = services.map.get(lid)
        err = np.hypot(saved.x - truth[0], saved.y - truth[1])
        assert err < 0.03, f"saved ({saved.x:.3f}, {saved.y:.3f}), truth {truth[:2]}"
    finally:
        sub.close()
        page.close()
