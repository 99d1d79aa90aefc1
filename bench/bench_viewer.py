"""CPU cost of the viewer: 3 robots moving at 30 Hz, 30 landmarks, and 0, 1 and 5 connected
clients.

The clients are plain WebSocket clients speaking viser's protocol (they send one camera
message, then read everything), run in a separate process so that only the viewer's own
work (scene updates, viser serialisation and sending) is counted in this process. They
connect to viser directly on 127.0.0.1: the API proxy's relay (one more copy per message,
in the server process) is not included.

    .venv/bin/python bench/bench_viewer.py [--seconds 10] [--browsers]

`--browsers` adds rows with real browsers: pages of Debian's headless Chromium
(/usr/bin/chromium, driven by Playwright, software WebGL) in another process. They check that
a browser costs the viewer what a plain client does; on a 2-core machine Chromium takes most
of both cores, so the scene rate may drop while they run.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

from localizer.events import PoseEstimate
from sim.cameras import wide_angle_camera
from web.services import CameraView, Candidate, EventLine, LandmarkState, RobotState
from web.viewer import Viewer

CHROMIUM = "/usr/bin/chromium"


class SyntheticSite:
    """A read-only `ViewerSite` for viewer-role clients (no actions, no wizard): a 6x5
    landmark grid 1.2 m apart, 3 robots on circles."""

    def __init__(self) -> None:
        self.camera = wide_angle_camera("fisheye")
        self._lms = [
            LandmarkState(
                100 + 6 * j + i,
                1.2 * i,
                1.2 * j,
                2.5,
                supply_mv=2400 + 25 * (i + j),
                percent=30.0 + 8 * (i + j),
                days_left=50.0 + i,
            )
            for j in range(5)
            for i in range(6)
        ]
        self._t0 = time.monotonic_ns()

    def landmarks(self) -> list[LandmarkState]:
        return self._lms

    def robots(self) -> list[RobotState]:
        now = time.monotonic_ns() - self._t0
        t = now * 1e-9
        out = []
        for k in range(3):
            a = 0.3 * t + 2.1 * k
            x, y = 3.0 + 1.5 * math.cos(a), 2.4 + 1.5 * math.sin(a)
            cov = np.diag([1e-4, 2e-4, 1e-4]) * (1 + 0.5 * math.sin(t + k))
            ids = (100 + 6 * k, 101 + 6 * k)
            pose = PoseEstimate(now, x, y, a + math.pi / 2, cov, "landmark", ids)
            out.append(RobotState(f"r{k + 1}", self.camera, pose, "landmark", now, now))
        return out

    def lit(self) -> frozenset[int]:
        return frozenset(lm.id for lm in self._lms)

    def events(self, limit: int) -> list[EventLine]:
        return [EventLine("2026-01-01 00:00:00", "low_battery", "landmark 100 at 2.40 V")]

    def camera_view(self, robot: str) -> CameraView | None:
        return None

    def ceiling_height(self) -> float:
        return 2.5

    def to_identify(self, *, discover: bool = False) -> list[Candidate]:
        return []


async def _clients(port: int, n: int, seconds: float) -> list[int]:
    import msgspec
    import websockets
    from viser import _messages
    from websockets.typing import Subprotocol

    cam = _messages.ViewerCameraMessage(
        (1.0, 0.0, 0.0, 0.0),
        (0.0, -8.0, 6.0),
        1.0,
        0.01,
        100.0,
        800,
        1280,
        (3.0, 2.4, 1.0),
        (0.0, 0.0, 1.0),
    )
    hello = msgspec.msgpack.encode(cam.as_serializable_dict())
    counts = [0] * n

    async def one(i: int) -> None:
        async with websockets.connect(
            f"ws://127.0.0.1:{port}",
            subprotocols=[Subprotocol("viser-v1.1.1")],
            max_size=None,
        ) as ws:
            await ws.send(hello)
            end = time.monotonic() + seconds
            while (left := end - time.monotonic()) > 0:
                try:
                    msg = await asyncio.wait_for(ws.recv(), timeout=left)
                except TimeoutError:
                    break
                counts[i] += len(msg)

    await asyncio.gather(*(one(i) for i in range(n)))
    return counts


def _browsers(port: int, n: int, seconds: float) -> None:
    """`n` pages of headless Chromium on the viewer for `seconds` (bytes are not counted)."""
    from playwright.sync_api import sync_playwright

    args = ["--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run"]
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=args)
        pages = [browser.new_page(viewport={"width": 1280, "height": 800}) for _ in range(n)]
        for page in pages:
            page.goto(f"http://127.0.0.1:{port}/")
        time.sleep(seconds)
        browser.close()


def measure(
    viewer: Viewer, n_clients: int, seconds: float, *, browsers: bool = False
) -> dict[str, float]:
    proc = None
    if n_clients:
        kind = "--browser" if browsers else "--client"
        proc = subprocess.Popen(
            [
                sys.executable,
                __file__,
                kind,
                str(viewer.port),
                str(n_clients),
                str(seconds + (20 if browsers else 2)),
            ],
            stdout=subprocess.PIPE,
            text=True,
        )
        time.sleep(15.0 if browsers else 2.0)  # connect, load, receive the initial scene
    ticks0, t0, c0 = viewer.ticks, time.monotonic(), time.process_time()
    time.sleep(seconds)
    cpu, wall = time.process_time() - c0, time.monotonic() - t0
    rate = (viewer.ticks - ticks0) / wall
    out = {"clients": n_clients, "cpu_percent_of_one_core": 100 * cpu / wall, "updates_hz": rate}
    if proc is not None:
        stdout, _ = proc.communicate(timeout=120)
        if not browsers:
            counts = json.loads(stdout.strip().splitlines()[-1])
            out["kB_per_s_per_client"] = sum(counts) / len(counts) / (seconds + 2) / 1000
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args and args[0] in ("--client", "--browser"):
        port, n, seconds = int(args[1]), int(args[2]), float(args[3])
        if args[0] == "--browser":
            _browsers(port, n, seconds)
        else:
            print(json.dumps(asyncio.run(_clients(port, n, seconds))))
        return 0
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--browsers", action="store_true", help="also 1 and 5 Chromium pages")
    ns = p.parse_args(args)
    if ns.browsers and not os.path.exists(CHROMIUM):
        p.error(f"--browsers needs Debian's chromium at {CHROMIUM} (apt-get install chromium)")
    viewer = Viewer(SyntheticSite())
    viewer.start()
    try:
        time.sleep(2.0)
        print(
            "viewer CPU, 3 robots at 30 Hz, 30 landmarks; clients: plain WebSocket clients "
            "speaking viser's protocol in another process, connected to viser directly "
            f"(no proxy, no browser); {ns.seconds:.0f} s per row; load {os.getloadavg()[0]:.1f}"
        )
        for n in (0, 1, 5):
            r = measure(viewer, n, ns.seconds)
            extra = f", {r['kB_per_s_per_client']:.0f} kB/s per client" if n else ""
            print(
                f"  {n} clients: {r['cpu_percent_of_one_core']:5.1f} % of one core, "
                f"scene updates {r['updates_hz']:.1f} Hz{extra}"
            )
        for n in (1, 5) if ns.browsers else ():
            r = measure(viewer, n, ns.seconds, browsers=True)
            print(
                f"  {n} Chromium page(s): {r['cpu_percent_of_one_core']:5.1f} % of one core, "
                f"scene updates {r['updates_hz']:.1f} Hz (load {os.getloadavg()[0]:.1f})"
            )
    finally:
        viewer.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
