"""Live-site accuracy: run the demo site in-process (no HTTP) and print, every second, each
robot's mode and its error against the simulator's truth; then a summary per robot and mode.

    .venv/bin/python bench/bench_live_accuracy.py [SECONDS]

This measures the multi-robot case that the offline replays do not: robots share the LEDs,
and one robot's one-at-a-time identification sweep darkens the site for the others.
"""

from __future__ import annotations

import asyncio
import collections
import sys
import tempfile
import time

import numpy as np

from server.services import SiteServices
from server.settings import Settings


async def run(duration_s: float) -> None:
    services = SiteServices(Settings(data_dir=tempfile.mkdtemp(), viewer_enabled=False))
    await services.start()
    assert services.sim is not None
    t0 = time.time()
    errors: dict[tuple[str, str], list[float]] = collections.defaultdict(list)
    try:
        while time.time() - t0 < duration_s:
            await asyncio.sleep(1.0)
            line = [f"{time.time() - t0:5.1f} s"]
            for r in services.robots.runners():
                u = r.latest
                if u is None or u.x is None or u.y is None:
                    line.append(f"{r.name}: {r.mode}")
                    continue
                tx, ty, _ = services.sim.true_pose(r.name)
                e = float(np.hypot(u.x - tx, u.y - ty))
                errors[(r.name, u.mode)].append(e)
                line.append(f"{r.name}: {u.mode:<14} {100 * e:7.1f} cm")
            print(" | ".join(line), flush=True)
    finally:
        await services.stop()
    print("\nrobot  mode            samples  median cm  max cm")
    for (name, mode), v in sorted(errors.items()):
        a = np.array(v)
        print(f"{name:<6} {mode:<15} {len(a):7d} {100 * np.median(a):10.1f} {100 * a.max():7.1f}")


if __name__ == "__main__":
    asyncio.run(run(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0))
