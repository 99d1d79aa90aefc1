"""Virtual-site benchmark (bounded run time).

1. Frames rendered per second at 640x480 (fisheye and pinhole, ~12 lit landmarks in view,
   sensor noise), single thread; a plain copy of a 640x480 uint8 frame timed in the same run
   for reference (what the machine does in the same time).
2. CPU share of a live site (`demo`: three robots, 30 Hz cameras, 100 Hz odometry), stepped
   in real time every 10 ms for `--seconds`: process CPU time over wall time. Goal: < 25 %
   of one core.
3. `irloc simulate` throughput: simulated seconds per CPU second (PNG writing included).

Usage: .venv/bin/python bench/bench_sim.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

from irloc.simulated_recording import simulate_recording
from localizer.geometry import T_world_body_from_pose
from sim.cameras import LENSES, wide_angle_camera
from sim.render import RenderConfig, render_frame
from sim.scenario import load_scenario
from sim.virtual_site import VirtualSite


def bench_render(lens: str, frames: int = 300) -> float:
    """Frames per second."""
    camera = wide_angle_camera(lens)  # type: ignore[arg-type]
    g = np.stack(np.meshgrid(np.arange(-2.4, 2.5, 1.2), np.arange(-1.2, 1.3, 1.2)), -1)
    sources = np.column_stack([g.reshape(-1, 2), np.full(g.size // 2, 2.5)])
    T = T_world_body_from_pose(0.1, 0.2, 0.3)
    rng = np.random.default_rng(0)
    cfg = RenderConfig()
    render_frame(camera, T, sources, np.ones(len(sources)), rng=rng, config=cfg)  # warm pool
    t = time.perf_counter()
    for _ in range(frames):
        render_frame(camera, T, sources, np.ones(len(sources)), rng=rng, config=cfg)
    return frames / (time.perf_counter() - t)


def bench_copy(frames: int = 300) -> float:
    """Plain 640x480 uint8 copies per second."""
    a = np.random.default_rng(0).integers(0, 255, (480, 640), dtype=np.uint8)
    t = time.perf_counter()
    for _ in range(frames):
        a.copy()
    return frames / (time.perf_counter() - t)


def bench_live(seconds: float) -> tuple[float, int]:
    """(CPU share of one core, frames produced) of the demo site stepped in real time."""
    site = VirtualSite("demo")
    site.step(time.monotonic_ns())
    time.sleep(0.05)
    site.step(time.monotonic_ns())  # first frames: builds the noise pool, not timed
    frames = 0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    while time.perf_counter() - wall0 < seconds:
        time.sleep(0.01)
        frames += sum(1 for s in site.step(time.monotonic_ns()) if hasattr(s.event, "image"))
    return (time.process_time() - cpu0) / (time.perf_counter() - wall0), frames


def bench_offline(seconds: float) -> float:
    """Simulated seconds per CPU second of `irloc simulate` (one robot, PNGs written)."""
    scenario = load_scenario("paper_testbed")
    with tempfile.TemporaryDirectory() as d:
        cpu0 = time.process_time()
        simulate_recording(scenario, d, duration_s=seconds)
        return seconds / (time.process_time() - cpu0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="live-site run time")
    args = parser.parse_args()
    rows = [(f"render 640x480 {lens}", f"{bench_render(lens):.0f} frames/s") for lens in LENSES]
    rows.append(("copy 640x480 uint8 (reference)", f"{bench_copy():.0f} frames/s"))
    share, frames = bench_live(args.seconds)
    rows.append(
        (
            f"live demo site, 3 robots x 30 Hz, {args.seconds:.0f} s",
            f"{100 * share:.1f} % of one core ({frames} frames; goal < 25 %)",
        )
    )
    rows.append(("irloc simulate paper_testbed", f"{bench_offline(5.0):.2f} sim s per CPU s"))
    width = max(len(r[0]) for r in rows)
    print(f"{'benchmark':<{width}}  result")
    print(f"{'-' * width}  {'-' * 40}")
    for name, value in rows:
        print(f"{name:<{width}}  {value}")


if __name__ == "__main__":
    main()
