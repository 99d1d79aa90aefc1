"""Fleet benchmark: N robot agents (`irloc agent`) -> Mosquitto -> the site server
(`irloc serve --mqtt`) -> a WebSocket client of `/api/v1/poses/ws` (loopback, bounded time).

For each robot count (default 10, 50, 100) the agents run in separate processes
(`--per-process` robots each) on the demo site's world with the server's virtual robots off.
Up to `--real` robots (default 10) are real agents in the light mode (spot-level simulation:
no rendering, the same localizer), their cameras at `--camera-rate` frames/s (default 10,
the agent's default pose rate: every frame gives one pose message), odometry at
`--odometry-rate`, started on their docks (`--start-known`); their own CPU is reported per
robot. Larger counts are replay agents: the agent's own runtime and MQTT connection
(connection and will, status, clock exchanges, poses at 10/s, visualization at 1/s) with
poses along a circle instead of a localizer, so that a hundred fit on this machine; the
server cannot tell them apart. Once every robot is localized, over `--seconds`:
- latency from an agent's pose (`computed_wall_ns`, stamped when the agent's localizer
  returned it) to the WebSocket client receiving it: p50 / p99 / max, for 10 of the robots
  (`/poses/ws?robot=...`; parsing every robot's poses would make this process the
  bottleneck), and the same to a plain MQTT subscriber (the agent's and broker's share);
- the server's CPU (its process: utime + stime) above its idle level, per robot, in % of
  one core;
- bytes per second per robot on the broker, from the agent (poses, VDA 5050 visualization
  and connection, status, clock requests, LED requests) and to it (LED states, clock
  replies), counting MQTT's fixed header and topic, against streaming the frames instead
  (raw 8-bit, and PNG).
The cost curve is the server CPU against the robot count with a least-squares line.

Usage: .venv/bin/python bench/bench_fleet.py [--counts 10 50 100] [--seconds 8]
[--per-process 25] [--camera-rate 10]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import paho.mqtt.client as mqtt

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agent.core import AgentConfig, AgentCore, Outgoing  # noqa: E402
from agent.timebase import TimeBase  # noqa: E402
from fleet.payloads import MapMessage  # noqa: E402
from localizer.events import PoseEstimate  # noqa: E402
from tests.fleet.mosquitto import Mosquitto, free_port  # noqa: E402

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
SAMPLED = 10
"""Robots of each round whose latencies are measured (all of them load the server)."""
TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


class ByteCounter:
    """Bytes on the broker per robot, both directions (an MQTT PUBLISH: 2-byte fixed header,
    2-byte topic length, topic, 2-byte packet id at QoS 1, payload)."""

    def __init__(self, port: int) -> None:
        self.up: dict[str, int] = defaultdict(int)
        self.down: dict[str, int] = defaultdict(int)
        self.broadcast = 0
        self.to_broker_ms: list[tuple[float, str, float]] = []
        self.sampled: set[str] = set()
        """Robots whose pose latencies are taken (parsing every message would make this
        process the bottleneck)."""
        self._lock = threading.Lock()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)  # type: ignore[attr-defined]
        self.client.on_message = self._on
        self.client.on_connect = lambda c, *a: c.subscribe(
            [("irloc/v1/default/#", 1), ("uagv/v2/irloc/+/+", 1)]
        )
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _on(self, client: Any, userdata: Any, msg: mqtt.MQTTMessage) -> None:
        size = 2 + 2 + len(msg.topic) + (2 if msg.qos else 0) + len(msg.payload)
        parts = msg.topic.split("/")
        if parts[-1] == "pose" and parts[4] in self.sampled:
            wall = json.loads(msg.payload)["wall_ns"]
            self.to_broker_ms.append((time.monotonic(), parts[4], (time.time_ns() - wall) / 1e6))
        with self._lock:
            if parts[0] == "uagv":
                self.up[parts[3]] += size
            elif len(parts) >= 5 and parts[3] == "agents":
                if parts[5:6] in (["command"], ["clock"]):
                    self.down[parts[4]] += size
                else:
                    self.up[parts[4]] += size
            elif parts[3] == "clock":
                robot = json.loads(msg.payload).get("robot", "?")
                self.up[robot] += size
            elif parts[3] in ("leds", "map"):
                self.broadcast += size  # every agent receives each of these

    def snapshot(self) -> tuple[dict[str, int], dict[str, int], int]:
        with self._lock:
            return dict(self.up), dict(self.down), self.broadcast


class Latencies:
    """A WebSocket client of the pose stream, recording pose -> client latency (ms)."""

    def __init__(self, url: str) -> None:
        from websockets.sync.client import connect

        self.ws = connect(url, max_size=2**24)
        self.samples: list[tuple[float, str, float]] = []
        self._stop = False
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self._stop:
            try:
                text = self.ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            except Exception:
                return
            now = time.time_ns()
            t = time.monotonic()
            for p in json.loads(text):
                self.samples.append((t, p["robot"], (now - p["computed_wall_ns"]) / 1e6))

    def close(self) -> None:
        self._stop = True
        self.thread.join(2)
        self.ws.close()


def frame_sizes(camera_rate: float) -> tuple[int, int, float]:
    """(raw bytes, PNG bytes) of one rendered frame of the demo's robot r1, and its rate."""
    import cv2

    from agent.sim_source import SimRobotSource
    from localizer.events import FrameObserved
    from sim.scenario import load_scenario

    src = SimRobotSource(load_scenario("demo"), "r1")
    src.step(0)
    for i in range(1, 100):
        for ev in src.step(i * 10_000_000):
            if isinstance(ev, FrameObserved):
                _ok, png = cv2.imencode(".png", ev.image)
                return ev.image.size, len(png), src.rig.spec.camera.rate_hz
    raise RuntimeError("no frame rendered")


def start_server(broker: Mosquitto, data_dir: Path) -> tuple[subprocess.Popen[str], int, str]:
    port = free_port()
    cmd = [
        sys.executable,
        "-m",
        "irloc",
        "serve",
        "--port",
        str(port),
        "--mqtt",
        broker.url,
        "--no-viewer",
        "--no-sim-robots",
        "--data-dir",
        str(data_dir),
        "--log-level",
        "warning",
    ]
    env = {**ENV, "IRLOC_MQTT_AGENTS": '["*"]'}  # the benchmark's agents, on an open broker
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True, cwd=ROOT)
    assert proc.stdout is not None
    key = ""
    for line in proc.stdout:
        if "admin API key" in line:
            key = line.rsplit(": ", 1)[1].strip()
            break
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=1)
            return proc, port, key
        except OSError:
            time.sleep(0.2)
    raise RuntimeError("server did not come up")


def robots(port: int, key: str) -> list[dict[str, Any]]:
    req = urllib.request.Request(
        f"http://127.0.0.1:{port}/api/v1/robots", headers={"Authorization": f"Bearer {key}"}
    )
    return list(json.loads(urllib.request.urlopen(req, timeout=10).read()))


class ReplayCore(AgentCore):
    """A stand-in agent for the large counts: a real agent's messages, the poses along a
    circle (radius 2 m, 0.3 m/s), no localizer."""

    def tick(self, now_mono_ns: int) -> list[Outgoing]:
        with self._inbox_lock:
            inbox, self._inbox = self._inbox, []
        for msg in inbox:
            if isinstance(msg, MapMessage):
                self.map_id = msg.map_id
        if (now_mono_ns - self._last_pose_mono) * self.config.pose_rate_hz < 0.8e9:
            return []
        self.frames += 1
        self.mode = "landmark"
        a = 0.15 * now_mono_ns * 1e-9 + hash(self.config.name) % 628 / 100
        cov = np.diag([2e-5, 2e-5, 1e-5])
        est = PoseEstimate(
            now_mono_ns, 5 + 2 * np.cos(a), 3 + 2 * np.sin(a), a % 3.1, cov, "landmark", (101, 102)
        )
        return self._pose_out(est, now_mono_ns)


def replay_worker(url: str, name: str, count: int) -> int:
    """A process of `count` replay agents (run by the benchmark itself)."""
    import asyncio

    from agent.runtime import AgentRuntime
    from agent.sim_source import SimRobotSource
    from fleet.broker import parse_broker_url
    from sim.scenario import load_scenario

    source = SimRobotSource(load_scenario("demo"), "r1", light=True)
    cores: list[AgentCore] = [
        ReplayCore(AgentConfig(f"{name}-{i:03d}", source="sim-light"), source, TimeBase())
        for i in range(count)
    ]
    stop = asyncio.Event()

    async def run() -> None:
        asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stop.set)
        await AgentRuntime(parse_broker_url(url), "default", cores).run(stop)

    asyncio.run(run())
    return 0


def _agents(
    n: int, name: str, count: int, args: argparse.Namespace, broker: Mosquitto
) -> subprocess.Popen[bytes]:
    """One process of `count` agents: real (light) ones up to `--real` robots, else replay."""
    if n > args.real:
        cmd = [
            sys.executable,
            str(Path(__file__).resolve()),
            "--replay-worker",
            broker.url,
            name,
            str(count),
        ]
    else:
        cmd = [
            sys.executable,
            "-m",
            "irloc",
            "agent",
            "--mqtt",
            broker.url,
            "--name",
            name,
            "--count",
            str(count),
            "--sim",
            "--light",
            "--camera-rate",
            str(args.camera_rate),
            "--start-known",
            "--log-level",
            "warning",
        ]
        if args.odometry_rate is not None:
            cmd += ["--odometry-rate", str(args.odometry_rate)]
        if count == 1:
            cmd += ["--robot", "r1"]
    return subprocess.Popen(cmd, env=ENV, cwd=ROOT, stdout=subprocess.DEVNULL)


def stop_agents(procs: list[subprocess.Popen[bytes]]) -> None:
    """End agent processes (SIGTERM: their agents go OFFLINE), killing any that hang."""
    for p in procs:
        p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(15)
        except subprocess.TimeoutExpired:
            p.kill()


def _pct(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) if len(a) else float("nan")


def run_round(
    n: int,
    args: argparse.Namespace,
    broker: Mosquitto,
    server: subprocess.Popen[str],
    port: int,
    key: str,
    counter: ByteCounter,
    idle_core: float,
) -> dict[str, Any]:
    prefix = f"n{n}"
    procs = []
    for k, start in enumerate(range(0, n, args.per_process)):
        count = min(args.per_process, n - start)
        procs.append(_agents(n, f"{prefix}p{k}", count, args, broker))
    try:
        deadline = time.monotonic() + args.warmup_s
        ready = 0
        slow_answers = 0
        while time.monotonic() < deadline:
            try:
                listed = robots(port, key)
            except OSError:  # a server too busy to answer in 10 s: count it and go on
                slow_answers += 1
                continue
            mine = [r for r in listed if r["name"].startswith(prefix)]
            ready = sum(r["mode"] == "landmark" and bool(r["connected"]) for r in mine)
            if ready == n:
                break
            time.sleep(0.5)
        names = []  # as `irloc agent --count` names them (no suffix for a count of 1)
        for k, start in enumerate(range(0, n, args.per_process)):
            count = min(args.per_process, n - start)
            base = f"{prefix}p{k}"
            names += [base] if count == 1 else [f"{base}-{i:03d}" for i in range(count)]
        sample = names[:: max(1, len(names) // SAMPLED)]
        counter.sampled = set(sample)
        query = "".join(f"&robot={r}" for r in sample)
        lat = Latencies(f"ws://127.0.0.1:{port}/api/v1/poses/ws?token={key}{query}")
        time.sleep(1.0)
        up0, down0, b0 = counter.snapshot()
        a0 = sum(cpu_s(p.pid) for p in procs)
        c0, t0 = cpu_s(server.pid), time.monotonic()
        time.sleep(args.seconds)
        c1, t1 = cpu_s(server.pid), time.monotonic()
        a1 = sum(cpu_s(p.pid) for p in procs)
        up1, down1, b1 = counter.snapshot()
        lat.close()
    finally:
        stop_agents(procs)
    dt = t1 - t0
    ms = np.array([s[2] for s in lat.samples if t0 <= s[0] <= t1 and s[1] in counter.sampled])
    hop = np.array(
        [s[2] for s in counter.to_broker_ms if t0 <= s[0] <= t1 and s[1].startswith(prefix)]
    )
    mine_up = sum(up1.get(r, 0) - up0.get(r, 0) for r in up1 if r.startswith(prefix))
    mine_down = sum(down1.get(r, 0) - down0.get(r, 0) for r in down1 if r.startswith(prefix))
    core = (c1 - c0) / dt
    return {
        "robots": n,
        "kind": "replay" if n > args.real else "light",
        "localized": ready,
        "poses_s": len(ms) / dt * n / len(counter.sampled),
        "p50": _pct(ms, 50),
        "p99": _pct(ms, 99),
        "max": float(ms.max()) if len(ms) else float("nan"),
        "hop_p50": _pct(hop, 50),
        "hop_p99": _pct(hop, 99),
        "core_pct": 100 * core,
        "per_robot_pct": 100 * (core - idle_core) / n,
        "agent_pct": 100 * (a1 - a0) / dt / n,
        "up_Bps": mine_up / dt / n,
        "down_Bps": mine_down / dt / n + (b1 - b0) / dt,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--counts", type=int, nargs="+", default=[10, 50, 100])
    p.add_argument("--seconds", type=float, default=8.0)
    p.add_argument("--per-process", type=int, default=25)
    p.add_argument("--camera-rate", type=float, default=10.0)
    p.add_argument("--odometry-rate", type=float, help="simulated wheel samples/s (100)")
    p.add_argument("--warmup-s", type=float, default=60.0)
    p.add_argument("--real", type=int, default=10, help="real agents up to this many robots")
    p.add_argument("--replay-worker", nargs=3, metavar=("URL", "NAME", "COUNT"), help="internal")
    args = p.parse_args(argv)
    if args.replay_worker:
        url, name, count = args.replay_worker
        return replay_worker(url, name, int(count))
    raw, png, rate = frame_sizes(args.camera_rate)
    rows = []
    with Mosquitto() as broker, tempfile.TemporaryDirectory() as tmp:
        server, port, key = start_server(broker, Path(tmp))
        try:
            counter = ByteCounter(broker.port)
            time.sleep(2.0)
            c0, t0 = cpu_s(server.pid), time.monotonic()
            time.sleep(4.0)
            idle = (cpu_s(server.pid) - c0) / (time.monotonic() - t0)
            print(f"server idle (site clock, LEDs, no robots): {100 * idle:.1f} % of a core")
            for n in args.counts:
                row = run_round(n, args, broker, server, port, key, counter, idle)
                rows.append(row)
                print(
                    f"  {n} robots: {row['localized']} localized, {row['poses_s']:.0f} poses/s "
                    f"at the client, server {row['core_pct']:.1f} % of a core",
                    flush=True,
                )
                time.sleep(2.0)
        finally:
            server.send_signal(signal.SIGTERM)
            server.wait(20)
    print()
    print(
        "| robots (agents) | localized | poses/s (all robots) | latency p50 / p99 / max (ms) | "
        "to "
        "broker subscriber p50 / p99 (ms) | server CPU (% core) | server per robot (% core) | "
        "agent CPU per robot (% core) | B/s per robot from / to agent |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['robots']} ({r['kind']}) | {r['localized']} | {r['poses_s']:.0f} | "
            f"{r['p50']:.1f} / "
            f"{r['p99']:.1f} / {r['max']:.1f} | {r['hop_p50']:.1f} / {r['hop_p99']:.1f} | "
            f"{r['core_pct']:.1f} | {r['per_robot_pct']:.2f} | {r['agent_pct']:.1f} | "
            f"{r['up_Bps']:.0f} / {r['down_Bps']:.0f} |"
        )
    if len(rows) >= 2:
        n = np.array([r["robots"] for r in rows], float)
        c = np.array([r["core_pct"] for r in rows])
        slope, icpt = np.polyfit(n, c, 1)
        print(f"\ncost curve: server CPU = {icpt:.1f} % + {slope:.3f} % per robot (least squares)")
    print(
        f"streaming the frames instead: {raw * rate / 1e3:.0f} kB/s raw, {png * rate / 1e3:.0f} "
        f"kB/s PNG per robot ({raw} B raw, {png} B PNG per frame at {rate:.0f} Hz)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
