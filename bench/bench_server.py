"""Server streaming and request benchmark (loopback only, bounded run time).

1. 10 robots at 30 Hz: each robot's `RobotRunner` is fed 30 events/s and publishes on the
   real pose bus; 50 WebSocket clients (in this process, one asyncio loop) plus one
   deliberately slow client (reads one message a second) receive `/api/v1/poses/ws`.
   Reported: p50/p99/max latency from pose computed (`computed_wall_ns`) to client receipt,
   poses missed by clients that keep up, drops counted for the slow one.
2. `GET /api/v1/robots/{name}/pose` requests/s with one uvicorn worker (8 keep-alive
   connections, raw HTTP/1.1 from this process).

The server runs in a subprocess (one worker). The localizers are stand-ins that output a
pose per event (this measures the server, not the localizer: see bench/ of the localizer).

Usage: .venv/bin/python bench/bench_server.py [--seconds 8] [--clients 50]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROBOTS = 10
RATE_HZ = 30.0


# -- server side (run in the subprocess) ------------------------------------------------------
class _StandInLocalizer:
    """Outputs one pose per odometry event along a circle (no estimation)."""

    def __init__(self, phase: float) -> None:
        self.phase = phase
        self.mode = "landmark"

    def handle(self, event: object) -> list[object]:
        from localizer.events import PoseEstimate

        t = event.t_ns  # type: ignore[attr-defined]
        a = self.phase + t * 1e-9 * 0.3
        cov = np.diag([1e-4, 1e-4, 1e-3])
        return [PoseEstimate(t, 3 * np.cos(a), 3 * np.sin(a), a % 3.0, cov, "landmark", (1, 2))]

    def set_map(self, landmark_map: object) -> None:
        pass


def serve(port: int, data_dir: str, key_file: str) -> None:
    import uvicorn

    from localizer.camera import camera_from_sensor  # noqa: F401  (import cost up front)
    from localizer.events import OdometryMeasured
    from localizer.robot import RobotGeometry
    from server.main import create_app
    from server.settings import Settings
    from server.site.robot import RobotRunner

    settings = Settings(
        data_dir=Path(data_dir),
        site_enabled=False,
        viewer_enabled=False,
        port=port,
        battery_interval_s=None,
        pose_queue=64,
    )
    app = create_app(settings)
    stop = threading.Event()

    def feed() -> None:
        while not hasattr(app.state, "services"):
            time.sleep(0.05)
        s = app.state.services
        Path(key_file).write_text(s.keys.create("viewer", "bench")[0])
        runners = []
        for i in range(ROBOTS):
            r = RobotRunner(
                f"r{i}",
                None,
                RobotGeometry(0.4),
                _StandInLocalizer(i),  # type: ignore[arg-type]
                publish=s.poses.publish,
                request_leds=lambda *_: None,
            )
            s.robots.add(r)
            runners.append(r)
        period = 1.0 / RATE_HZ
        next_t = time.monotonic()
        while not stop.is_set():
            for r in runners:
                r.handle(OdometryMeasured(time.monotonic_ns(), 0.1, 0.1))
            next_t += period
            stop.wait(max(0.0, next_t - time.monotonic()))

    threading.Thread(target=feed, daemon=True).start()
    uvicorn.Server(
        uvicorn.Config(
            app,
            host="127.0.0.1",
            port=port,
            log_level="warning",
            ws="websockets-sansio",
            lifespan="on",
        )
    ).run()
    stop.set()


# -- client side ---------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _client(url: str, key: str, window: tuple[float, float], slow: bool, out: dict) -> None:
    """Receive poses; only those received inside `window` (monotonic seconds) count."""
    import websockets

    lat: list[float] = []
    seen: set[tuple[str, int]] = set()
    n = 0
    async with websockets.connect(
        url,
        additional_headers={"Authorization": f"Bearer {key}"},
        max_queue=None if not slow else 1,
    ) as ws:
        while time.monotonic() < window[1]:
            try:
                left = max(0.01, window[1] - time.monotonic())
                text = await asyncio.wait_for(ws.recv(), timeout=left)
            except TimeoutError:
                break
            now = time.time_ns()
            inside = time.monotonic() >= window[0]
            for p in json.loads(text):
                if inside:
                    n += 1
                    lat.append((now - p["computed_wall_ns"]) / 1e6)
                    seen.add((p["robot"], p["t_ns"]))
            if slow:
                await asyncio.sleep(1.0)
    out.update(latencies=lat, received=n, seen=seen)


async def _stream_bench(port: int, key: str, clients: int, seconds: float) -> dict:
    url = f"ws://127.0.0.1:{port}/api/v1/poses/ws"
    outs: list[dict] = [{} for _ in range(clients + 1)]
    t0 = time.monotonic() + 2.0  # connect and warm up first
    window = (t0, t0 + seconds)
    tasks = [_client(url, key, window, False, outs[i]) for i in range(clients)]
    tasks.append(_client(url, key, window, True, outs[-1]))
    await asyncio.gather(*tasks)
    return {"fast": outs[:-1], "slow": outs[-1]}


def _metric(port: int, key: str, name: str) -> float:
    import httpx

    text = httpx.get(
        f"http://127.0.0.1:{port}/api/v1/metrics", headers={"Authorization": f"Bearer {key}"}
    ).text
    for line in text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return float("nan")


async def _http_bench(port: int, key: str, seconds: float, conns: int = 8) -> tuple[int, int]:
    req = (
        f"GET /api/v1/robots/r3/pose HTTP/1.1\r\nHost: 127.0.0.1\r\n"
        f"Authorization: Bearer {key}\r\n\r\n"
    ).encode()
    counts = [0] * conns
    bad = [0]

    async def one(i: int) -> None:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            writer.write(req)
            head = await reader.readuntil(b"\r\n\r\n")
            length = int(head.lower().split(b"content-length:")[1].split(b"\r\n")[0])
            await reader.readexactly(length)
            if not head.startswith(b"HTTP/1.1 200"):
                bad[0] += 1
            counts[i] += 1
        writer.close()

    await asyncio.gather(*(one(i) for i in range(conns)))
    return sum(counts), bad[0]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument(
        "--serve", nargs=3, metavar=("PORT", "DATA_DIR", "KEY_FILE"), help=argparse.SUPPRESS
    )
    args = ap.parse_args(argv)
    if args.serve:
        serve(int(args.serve[0]), args.serve[1], args.serve[2])
        return 0
    port = _free_port()
    with tempfile.TemporaryDirectory() as tmp:
        key_file = Path(tmp) / "key"
        proc = subprocess.Popen(
            [sys.executable, __file__, "--serve", str(port), tmp, str(key_file)],
            env={**os.environ, "PYTHONPATH": os.getcwd()},
        )
        try:
            for _ in range(300):
                if key_file.exists() and key_file.read_text():
                    break
                time.sleep(0.1)
            key = key_file.read_text()
            time.sleep(0.5)
            res = asyncio.run(_stream_bench(port, key, args.clients, args.seconds))
            lat = np.concatenate([np.asarray(o["latencies"]) for o in res["fast"]])
            # poses any fast client saw in the window: the ones published then (but for the
            # window's edges); a fast client missing one of them lost it
            union = set().union(*(o["seen"] for o in res["fast"]))
            edge = {
                (r, t)
                for r, t in union
                if sum((r, t) in o["seen"] for o in res["fast"]) < len(res["fast"]) // 2
            }
            missed = [len(union - edge - o["seen"]) for o in res["fast"]]
            dropped = _metric(port, key, "irloc_pose_bus_dropped_total")
            print(
                f"stream: {ROBOTS} robots x {RATE_HZ:.0f} Hz -> {args.clients} clients "
                f"+ 1 slow, {args.seconds:.0f} s measured after 2 s warm-up"
            )
            print(
                f"  latency ms: p50 {np.percentile(lat, 50):.1f}  p99 "
                f"{np.percentile(lat, 99):.1f}  max {lat.max():.1f}  (target p99 <= 50)"
            )
            print(
                f"  poses in the window: {len(union)} (expected ~"
                f"{ROBOTS * RATE_HZ * args.seconds:.0f}); missed by fast clients: total "
                f"{sum(missed)}, worst client {max(missed)}"
            )
            print(
                f"  slow client received {res['slow']['received']} in the window; "
                f"pose bus drops (whole run, all subscribers) {dropped:.0f}"
            )
            n, bad = asyncio.run(_http_bench(port, key, 5.0))
            print(
                f"GET /robots/r3/pose: {n / 5.0:.0f} requests/s, one worker, "
                f"8 connections ({bad} non-200) (target >= 1000)"
            )
        finally:
            proc.terminate()
            proc.wait(10)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
