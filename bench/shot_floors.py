"""The viewer on the two-floor demo with the first floor shown, for docs/img/viewer-floors.png:
an office plan uploaded for floor 1 (`FloorPlans.of("1")`, as `PUT /map/floorplan?floor=1`),
a dwell-watched zone at its lift and one on the ground floor, then Debian's Chromium
(Playwright) picks "First floor" in the Floor folder and takes the picture.

    .venv/bin/python bench/shot_floors.py [--out docs/img/viewer-floors.png]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import uvicorn

from irloc.serve import make_viewer
from live.settings import Settings
from server.main import create_app
from store.floorplan import Placement
from tests.web.test_browser import ARGS, CHROMIUM, throttle_frames


def office_plan() -> bytes:
    """A 10 x 5 m office floor at 100 px/m: two offices, a corridor, the lift."""
    img = np.full((500, 1000, 3), 250, np.uint8)
    dark = (60, 60, 60)
    cv2.rectangle(img, (0, 0), (999, 499), dark, 8)
    for x in (300, 600):
        cv2.line(img, (x, 0), (x, 260), dark, 6)
    cv2.line(img, (0, 260), (640, 260), dark, 6)
    cv2.rectangle(img, (760, 180), (880, 320), (120, 120, 200), -1)
    for x, y, text in ((60, 130, "Office A"), (360, 130, "Office B"), (80, 400, "Corridor")):
        cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 1.2, (90, 90, 90), 2)
    ok, png = cv2.imencode(".png", img)
    assert ok
    return png.tobytes()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/img/viewer-floors.png"))
    args = ap.parse_args()
    data = Path(tempfile.mkdtemp())
    settings = Settings(data_dir=data, port=0, viewer_port=0, scenario="two_floors", seed=5)
    app = create_app(settings, make_viewer(settings))
    config = uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning", log_config=None)
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.1)
    port = server.servers[0].sockets[0].getsockname()[1]
    services = app.state.services
    key = services.keys.create("admin", "screenshot")[0]
    place = Placement((0, 0), (0.0, 5.0), (1000, 0), (10.0, 5.0))
    services.floorplans.of("1").put(office_plan(), "image/png", place)
    lobby = [(6.6, 1.2), (9.6, 1.2), (9.6, 3.6), (6.6, 3.6)]
    services.zones.create("lift lobby", lobby, floor="1", dwell_s=60)
    services.zones.create("hall dock", [(0, 0), (2.4, 0), (2.4, 1.8), (0, 1.8)], floor="0")
    from playwright.sync_api import sync_playwright

    try:
        with sync_playwright() as p:
            ctx = p.chromium.launch_persistent_context(
                tempfile.mkdtemp(),
                executable_path=str(CHROMIUM),
                headless=True,
                args=ARGS,
                viewport={"width": 1280, "height": 800},
            )
            ctx.add_init_script(script=throttle_frames(10))
            page = ctx.new_page()
            page.set_default_timeout(90_000)
            page.goto(f"http://127.0.0.1:{port}/viewer/?token={key}")
            page.get_by_text("signed in as admin").wait_for()
            page.get_by_label("Show", exact=True).click()
            page.get_by_role("option", name="First floor (offices) (1)").click()
            page.wait_for_function("() => !!window.__viserMutable.nodeRefFromName['/floorplan']")
            time.sleep(5.0)  # the robots move on, the plan's texture loads
            notice = page.locator(".mantine-Notification-root", has_text="Software WebGL")
            if notice.count():
                notice.first.locator("button").first.click()
            page.screenshot(path=str(args.out))
            ctx.close()
    finally:
        server.should_exit = True
        thread.join(30)
        shutil.rmtree(data, ignore_errors=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
