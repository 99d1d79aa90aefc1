"""Server streaming and request benchmark (loopback only, bounded run time).

1. 10 robots at 30 Hz: each robot's `RobotRunner` is fed 30 events/s, unsynchronised (robot i
   at phase i/10 of the period), and publishes on the real pose bus; 50 WebSocket clients
   that keep up (in 2 client processes, never in the server's) plus one deliberately slow
   client (reads once a second, small receive buffer) receive `/api/v1/poses/ws`.
   Reported: p50/p99/max latency from pose computed (`computed_wall_ns`) to the bytes reaching
   the client process, poses missed by clients that keep up, drops counted for the slow one,
   the server's CPU use.
2. `GET /api/v1/robots/{name}/pose` requests/s with one uvicorn worker (8 keep-alive
   connections, raw HTTP/1.1 from this process).

The server runs in a subprocess (one worker). The localizers are stand-ins that output a
pose per event (this measures the server, not the localizer: see bench/ of the localizer).

Usage: .venv/bin/python bench/bench_server.py [--seconds 8] [--clients 50] [--client-procs 2]
[--flush-s S]; with IRLOC_BENCH_PROFILE=FILE the server's event-loop thread is profiled
(cProfile) into FILE (read it with `python -m pstats FILE`).
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROBOTS = 10
RATE_HZ = 30.0
SERVER_SNDBUF = 64 * 1024


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


def serve(port: int, data_dir: str, key_file: str, flush_s: str) -> None:
    import uvicorn

    from live.robots import RobotRunner
    from live.settings import Settings
    from localizer.camera import camera_from_sensor  # noqa: F401  (import cost up front)
    from localizer.events import OdometryMeasured
    from localizer.robot import RobotGeometry
    from server.main import create_app

    settings = Settings(
        data_dir=Path(data_dir),
        site_enabled=False,
        viewer_enabled=False,
        port=port,
        battery_interval_s=None,
        pose_queue=64,
    )
    if flush_s:
        settings.ws_flush_s = float(flush_s)
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
                None,  # type: ignore[arg-type]  # no camera: odometry events only
                RobotGeometry(0.4),
                _StandInLocalizer(i),  # type: ignore[arg-type]
                publish=s.poses.publish,
                request_leds=lambda *_: None,
            )
            s.robots.add(r)
            runners.append(r)
        # the robots' cameras are not synchronised: robot i's frames come at phase i / ROBOTS
        # of the frame period, so poses arrive one at a time, 3.3 ms apart
        slot = 1.0 / RATE_HZ / ROBOTS
        next_t = time.monotonic()
        while not stop.is_set():
            for r in runners:
                r.handle(OdometryMeasured(time.monotonic_ns(), 0.1, 0.1))
                next_t += slot
                stop.wait(max(0.0, next_t - time.monotonic()))

    threading.Thread(target=feed, daemon=True).start()
    # accepted connections inherit the listening socket's send buffer: a fixed SERVER_SNDBUF
    # instead of Linux's autotuning up to 4 MB, so a slow client's backlog reaches the
    # server's bounded queue in about a second instead of after half a minute
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SERVER_SNDBUF)
    sock.bind(("127.0.0.1", port))
    config = uvicorn.Config(
        app, log_level="warning", ws="websockets-sansio", lifespan="on"
    )  # uvloop and httptools when installed (the defaults' "auto")
    profile_to = os.environ.get("IRLOC_BENCH_PROFILE")
    if profile_to:  # the event loop's thread (uvicorn runs in the main thread)
        import cProfile
        import signal

        # uvicorn re-raises SIGTERM after its shutdown: ignore it then, so the stats get written
        signal.signal(signal.SIGTERM, lambda *_: None)

        cProfile.runctx(
            "uvicorn.Server(config).run(sockets=[sock])", globals(), locals(), profile_to
        )
    else:
        uvicorn.Server(config).run(sockets=[sock])
    stop.set()


# -- client side (client processes) -------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _PoseClient(asyncio.Protocol):
    """One WebSocket client: the `websockets` sans-I/O protocol on an asyncio transport (no
    task switch per message, so 25 clients in a process cost little CPU). Latency = the wall
    time when the message's last bytes reached this process minus the pose's
    `computed_wall_ns`. A slow client stops reading for `pause_s` after each message (its
    small receive buffer then fills and TCP flow control pushes back on the server)."""

    def __init__(self, url: str, key: str, window: tuple[float, float], pause_s: float) -> None:
        from websockets.client import ClientProtocol
        from websockets.uri import parse_uri

        self.ws = ClientProtocol(parse_uri(url), max_size=None)
        self.request = self.ws.connect()
        self.request.headers["Authorization"] = f"Bearer {key}"
        self.window = window
        self.pause_s = pause_s
        self.transport: asyncio.Transport | None = None
        self.latencies: list[float] = []
        self.seen: list[tuple[str, int, int]] = []
        self.received = 0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.ws.send_request(self.request)
        self._flush()

    def _flush(self) -> None:
        assert self.transport is not None
        for chunk in self.ws.data_to_send():
            if chunk:
                self.transport.write(chunk)

    def data_received(self, data: bytes) -> None:
        from websockets.frames import Frame, Opcode

        now = time.time_ns()
        self.ws.receive_data(data)
        for ev in self.ws.events_received():
            if not isinstance(ev, Frame) or ev.opcode is not Opcode.TEXT:
                continue
            if now >= self.window[0] * 1e9:
                for p in json.loads(bytes(ev.data)):
                    self.received += 1
                    self.latencies.append((now - p["computed_wall_ns"]) / 1e6)
                    self.seen.append((p["robot"], p["t_ns"], p["computed_wall_ns"]))
            if self.pause_s > 0 and self.transport is not None:
                self.transport.pause_reading()
                asyncio.get_running_loop().call_later(self.pause_s, self.transport.resume_reading)
        self._flush()

    def result(self) -> dict[str, Any]:
        return {
            "latencies": self.latencies,
            "received": self.received,
            "seen": self.seen,
            "slow": self.pause_s > 0,
        }


def _same(proto: _PoseClient) -> _PoseClient:
    return proto


async def _clients(
    url: str, key: str, n_fast: int, n_slow: int, t0: float, t1: float
) -> list[dict[str, Any]]:
    host, port = url.split("/")[2].split(":")
    loop = asyncio.get_running_loop()
    protos = []
    for i in range(n_fast + n_slow):
        slow = i >= n_fast
        sock = socket.socket()
        if slow:  # a small receive buffer: a client on a slow link backs up quickly
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.connect((host, int(port)))
        sock.setblocking(False)
        proto = _PoseClient(url, key, (t0, t1), 1.0 if slow else 0.0)
        await loop.create_connection(functools.partial(_same, proto), sock=sock)
        protos.append(proto)
    await asyncio.sleep(max(0.0, t1 - time.time()))
    return [p.result() for p in protos]


def run_clients(url: str, key: str, n_fast: int, n_slow: int, t0: float, t1: float) -> None:
    """One client process: `n_fast` clients that keep up and `n_slow` slow ones on one
    asyncio loop; prints their results as one JSON line."""
    cpu0 = time.process_time()
    outs = asyncio.run(_clients(url, key, n_fast, n_slow, t0, t1))
    print(json.dumps({"clients": outs, "cpu_s": time.process_time() - cpu0}))


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of process `pid` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _stream_bench(
    port: int, key: str, clients: int, procs: int, seconds: float, server_pid: int
) -> dict[str, Any]:
    """Start `procs` client processes (the slow client in the first), measure `seconds`
    after a 2 s warm-up, return every client's results and the server's CPU use."""
    url = f"ws://127.0.0.1:{port}/api/v1/poses/ws"
    t0 = time.time() + 2.0 + 0.3 * procs  # interpreter start, connect and warm up first
    t1 = t0 + seconds
    shares = [clients // procs + (i < clients % procs) for i in range(procs)]
    runs = [
        subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--run-clients",
                url,
                key,
                str(n),
                str(int(i == 0)),
                repr(t0),
                repr(t1),
            ],
            stdout=subprocess.PIPE,
            env={**os.environ, "PYTHONPATH": os.getcwd()},
        )
        for i, n in enumerate(shares)
    ]
    time.sleep(max(0.0, t0 - time.time()))
    cpu0 = _cpu_s(server_pid)
    time.sleep(max(0.0, t1 - time.time()))
    server_cpu = _cpu_s(server_pid) - cpu0
    results = [json.loads(r.communicate(timeout=seconds + 60)[0]) for r in runs]
    outs = [c for res in results for c in res["clients"]]
    return {
        "fast": [o for o in outs if not o["slow"]],
        "slow": next(o for o in outs if o["slow"]),
        "server_cpu_s": server_cpu,
        "client_cpu_s": sum(res["cpu_s"] for res in results),
        "window": (t0, t1),
    }


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


def _missed(fast: list[dict[str, Any]], window: tuple[float, float]) -> list[int]:
    """Poses each fast client lacks among those computed well inside the window (0.2 s
    after its start to 0.5 s before its end, so no edge effect) that any client received."""
    lo, hi = (window[0] + 0.2) * 1e9, (window[1] - 0.5) * 1e9
    inner = [{(r, t) for r, t, w in o["seen"] if lo <= w <= hi} for o in fast]
    union = set().union(*inner)
    return [len(union - s) for s in inner]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--client-procs", type=int, default=2, help="client processes")
    ap.add_argument("--flush-s", type=float, default=None, help="server ws_flush_s")
    ap.add_argument("--serve", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("--run-clients", nargs=6, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.serve:
        serve(int(args.serve[0]), args.serve[1], args.serve[2], args.serve[3])
        return 0
    if args.run_clients:
        url, key, n, slow, t0, t1 = args.run_clients
        run_clients(url, key, int(n), int(slow), float(t0), float(t1))
        return 0
    port = _free_port()
    with tempfile.TemporaryDirectory() as tmp:
        key_file = Path(tmp) / "key"
        flush = "" if args.flush_s is None else repr(args.flush_s)
        proc = subprocess.Popen(
            [sys.executable, __file__, "--serve", str(port), tmp, str(key_file), flush],
            env={**os.environ, "PYTHONPATH": os.getcwd()},
        )
        try:
            for _ in range(300):
                if key_file.exists() and key_file.read_text():
                    break
                time.sleep(0.1)
            key = key_file.read_text()
            time.sleep(0.5)
            res = _stream_bench(port, key, args.clients, args.client_procs, args.seconds, proc.pid)
            lat = np.concatenate([np.asarray(o["latencies"]) for o in res["fast"]])
            missed = _missed(res["fast"], res["window"])
            n_fast = [o["received"] for o in res["fast"]]
            dropped = _metric(port, key, "irloc_ws_dropped_poses_total")
            bus_dropped = _metric(port, key, "irloc_pose_bus_dropped_total")
            print(
                f"stream: {ROBOTS} robots x {RATE_HZ:.0f} Hz -> {args.clients} clients "
                f"({args.client_procs} client processes) + 1 slow, {args.seconds:.0f} s "
                f"measured after a warm-up; load average {os.getloadavg()[0]:.1f}"
            )
            print(
                f"  latency pose computed -> client receipt, ms: p50 "
                f"{np.percentile(lat, 50):.1f}  p99 {np.percentile(lat, 99):.1f}  "
                f"max {lat.max():.1f}  (target p99 <= 50)"
            )
            print(
                f"  poses per fast client in the window: min {min(n_fast)} max {max(n_fast)} "
                f"(published ~{ROBOTS * RATE_HZ * args.seconds:.0f}); missed by fast clients "
                f"(inner window): total {sum(missed)}, worst client {max(missed)}"
            )
            print(
                f"  slow client (reads once a second, 4 KiB receive buffer; server send buffer "
                f"{SERVER_SNDBUF // 1024} KiB) received {res['slow']['received']}; "
                f"dropped for slow WebSocket clients {dropped:.0f}, pose bus drops "
                f"{bus_dropped:.0f} (whole run)"
            )
            print(
                f"  CPU in the window: server {res['server_cpu_s'] / args.seconds:.0%} of a "
                f"core, clients {res['client_cpu_s'] / args.seconds:.0%} of a core"
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
