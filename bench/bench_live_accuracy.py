"""Live-site accuracy: run the demo site in-process (no HTTP), compare every pose the robots
publish with the simulator's truth at the pose's time, and print per robot: time to the first
fix, share of frames per mode, and error percentiles in landmark and dead-reckoning mode.

    .venv/bin/python bench/bench_live_accuracy.py [--seconds 60] [--seed 0]

This measures the multi-robot case that the offline replays do not: the robots share the
LEDs, identify by darkening one landmark at a time while the others track, and learn from
each other's probes.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import tempfile
import time
from pathlib import Path

import numpy as np

from live.poses import PoseUpdate
from live.services import SiteServices
from live.settings import Settings


async def run(duration_s: float, seed: int = 0) -> None:
    settings = Settings(data_dir=Path(tempfile.mkdtemp()), viewer_enabled=False, seed=seed)
    services = SiteServices(settings)
    await services.start()
    sim = services.virtual_site
    assert sim is not None
    sub = services.robots.subscribe_poses(maxsize=100_000)
    updates: list[PoseUpdate] = []
    truths: dict[tuple[str, int], tuple[float, float, float] | None] = {}
    t_start = services.clock_ns()

    async def collect() -> None:  # keep the truth of each frame before it is forgotten
        while True:
            for u in await sub.get_batch():
                updates.append(u)
                truths[(u.robot, u.t_ns)] = sim.true_pose_at(u.robot, u.t_ns)

    task = asyncio.get_running_loop().create_task(collect())
    t0 = time.time()
    try:
        while time.time() - t0 < duration_s:
            await asyncio.sleep(5.0)
            modes = collections.Counter((u.robot, u.mode) for u in updates[-450:])
            print(f"{time.time() - t0:5.1f} s  {dict(sorted(modes.items()))}", flush=True)
    finally:
        task.cancel()
        await services.stop()
    report(updates, truths, t_start)


def report(
    updates: list[PoseUpdate],
    truths: dict[tuple[str, int], tuple[float, float, float] | None],
    t_start: int,
) -> None:
    by_robot: dict[str, list[PoseUpdate]] = collections.defaultdict(list)
    for u in updates:
        by_robot[u.robot].append(u)
    print(
        "\nrobot  frames  first fix s  landmark %  DR %  other %   p50 cm  p95 cm"
        "  max cm (landmark)"
        "   p95 cm (DR)"
    )
    for name, us in sorted(by_robot.items()):
        err: dict[str, list[float]] = collections.defaultdict(list)
        first = None
        for u in us:
            if u.x is None or u.y is None:
                continue
            if first is None:
                first = (u.t_ns - t_start) * 1e-9
            truth = truths.get((name, u.t_ns))
            if truth is not None:
                err[u.mode].append(100 * float(np.hypot(u.x - truth[0], u.y - truth[1])))
        n = len(us)
        modes = collections.Counter(u.mode for u in us)
        lm = np.array(err.get("landmark", [np.nan]))
        dr = np.array(err.get("dead_reckoning", [np.nan]))
        other = n - modes["landmark"] - modes["dead_reckoning"]
        print(
            f"{name:<6} {n:6d} {first if first is not None else float('nan'):12.2f}"
            f" {100 * modes['landmark'] / n:10.1f} {100 * modes['dead_reckoning'] / n:5.1f}"
            f" {100 * other / n:8.1f} {np.percentile(lm, 50):8.2f} {np.percentile(lm, 95):7.2f}"
            f" {np.max(lm):7.2f} {np.percentile(dr, 95):17.2f}"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="how long to run the site")
    parser.add_argument("--seed", type=int, default=0, help="the demo site's seed")
    args = parser.parse_args()
    asyncio.run(run(args.seconds, args.seed))
