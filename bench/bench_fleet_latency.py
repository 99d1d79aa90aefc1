"""Fleet latency benchmark: N agents -> Mosquitto -> the site's receipt of each pose.

For each agent count (default 10 and 100) the agents run in separate processes (25 per
process) as `bench/bench_fleet.py`'s replay agents: the agent's own runtime and MQTT
connection (connection and will, status, clock exchanges, poses at 10/s, visualization at
1/s) with poses along a circle instead of a localizer, so that a hundred fit on this machine.
The site (`SiteServices` with its MQTT bridge, the demo world's site clock and LEDs, no
virtual robots) runs in this process on its own event loop, as `irloc serve --mqtt` runs it,
without the HTTP layer.

Latency: from the agent stamping a pose (`wall_ns`, the site's wall clock as the agent's
clock exchange knows it, taken as the pose message is built) to the site publishing it on
its pose bus (`AgentRunner.receive`: decoded, checked, turned to the site clock): the
broker hop both ways and the server's MQTT reader. Over `--seconds` once every agent is
registered and sending: p50 / p99 / max in ms over every pose of every agent, poses/s
received against those expected (10/s per agent), and the site's CPU (this process: user
+ system) in % of one core.

Usage: PYTHONPATH=$PWD .venv/bin/python bench/bench_fleet_latency.py [--counts 10 100]
[--seconds 10] [--per-process 25] [--profile FILE] (the site's event loop over each window,
into FILE.<count>; read with `python -m pstats`)
"""

from __future__ import annotations

import argparse
import asyncio
import cProfile
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.bench_fleet import stop_agents  # noqa: E402
from live.mqtt_bridge import start_mqtt_bridge  # noqa: E402
from live.poses import PoseUpdate  # noqa: E402
from live.services import SiteServices  # noqa: E402
from live.settings import Settings  # noqa: E402
from tests.fleet.mosquitto import Mosquitto  # noqa: E402

FLEET_BENCH = ROOT / "bench" / "bench_fleet.py"
POSE_RATE_HZ = 10.0


class Receipts:
    """Every pose the site publishes: (monotonic receipt time, robot, latency ms)."""

    def __init__(self, services: SiteServices) -> None:
        self.samples: list[tuple[float, str, float]] = []
        bus = services.poses
        publish = bus.publish

        def stamped(upd: PoseUpdate) -> None:
            now = time.time_ns()
            self.samples.append((time.monotonic(), upd.robot, (now - upd.computed_wall_ns) / 1e6))
            publish(upd)

        bus.publish = stamped  # type: ignore[method-assign,assignment]  # the agents' runners take this


def spawn(url: str, prefix: str, n: int, per_process: int) -> list[subprocess.Popen[bytes]]:
    procs = []
    for k, start in enumerate(range(0, n, per_process)):
        count = min(per_process, n - start)
        cmd = [
            sys.executable,
            str(FLEET_BENCH),
            "--replay-worker",
            url,
            f"{prefix}p{k}",
            str(count),
        ]
        procs.append(
            subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        )
    return procs


async def run_round(
    n: int, args: argparse.Namespace, url: str, services: SiteServices, receipts: Receipts
) -> dict[str, Any]:
    prefix = f"n{n}"
    procs = spawn(url, prefix, n, args.per_process)
    try:
        deadline = time.monotonic() + args.warmup_s
        ready = 0
        while time.monotonic() < deadline:
            mine = [r for r in services.robots.runners() if r.name.startswith(prefix)]
            ready = sum(r.latest is not None for r in mine)
            if ready == n:
                break
            await asyncio.sleep(0.5)
        await asyncio.sleep(1.0)
        profile = cProfile.Profile() if args.profile else None
        if profile is not None:
            profile.enable()  # the site's event loop: this thread
        t0, c0 = time.monotonic(), time.process_time()
        await asyncio.sleep(args.seconds)
        t1, c1 = time.monotonic(), time.process_time()
        if profile is not None:
            profile.disable()
            profile.dump_stats(f"{args.profile}.{n}")
    finally:
        await asyncio.to_thread(stop_agents, procs)
    ms = np.array([s[2] for s in receipts.samples if t0 <= s[0] <= t1 and s[1].startswith(prefix)])
    dt = t1 - t0

    def pct(q: float) -> float:
        return float(np.percentile(ms, q)) if len(ms) else float("nan")

    return {
        "agents": n,
        "ready": ready,
        "poses_s": len(ms) / dt,
        "expected_s": n * POSE_RATE_HZ,
        "p50": pct(50),
        "p99": pct(99),
        "max": float(ms.max()) if len(ms) else float("nan"),
        "cpu_pct": 100 * (c1 - c0) / dt,
    }


async def bench(args: argparse.Namespace) -> list[dict[str, Any]]:
    rows = []
    with Mosquitto() as broker, tempfile.TemporaryDirectory() as tmp:
        settings = Settings(
            data_dir=Path(tmp),
            viewer_enabled=False,
            sim_robots=False,
            mqtt_url=broker.url,
            mqtt_agents=["*"],
            battery_interval_s=None,
            log_format="text",
        )
        services = SiteServices(settings)
        await services.start()
        receipts = Receipts(services)
        bridge = await start_mqtt_bridge(services)
        assert bridge is not None
        try:
            while bridge.connects < 1:
                await asyncio.sleep(0.1)
            t0, c0 = time.monotonic(), time.process_time()
            await asyncio.sleep(3.0)
            idle = 100 * (time.process_time() - c0) / (time.monotonic() - t0)
            print(f"site idle (site clock, LEDs, no robots): {idle:.1f} % of a core", flush=True)
            for n in args.counts:
                row = await run_round(n, args, broker.url, services, receipts)
                rows.append(row)
                print(
                    f"  {n} agents: {row['ready']} sending, {row['poses_s']:.0f} of "
                    f"{row['expected_s']:.0f} poses/s, p50 {row['p50']:.1f} ms, p99 "
                    f"{row['p99']:.1f} ms, site CPU {row['cpu_pct']:.1f} % of a core",
                    flush=True,
                )
                await asyncio.sleep(2.0)
        finally:
            await bridge.stop()
            await services.stop()
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--counts", type=int, nargs="+", default=[10, 100])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--per-process", type=int, default=25)
    p.add_argument("--warmup-s", type=float, default=60.0)
    p.add_argument("--profile", help="cProfile the site's event loop into PROFILE.<count>")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)  # the site's events (agents leaving) stay quiet
    load = Path("/proc/loadavg").read_text().split()[:3]
    print(f"load average {' '.join(load)} on {len(os.sched_getaffinity(0))} cores")
    rows = asyncio.run(bench(args))
    print()
    print(
        "| agents | sending | poses/s received (nominal) | pose -> site p50 / p99 / max (ms) "
        "| site CPU (% of a core) |"
    )
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['agents']} | {r['ready']} | {r['poses_s']:.0f} ({r['expected_s']:.0f}) | "
            f"{r['p50']:.1f} / {r['p99']:.1f} / {r['max']:.1f} | {r['cpu_pct']:.1f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
