"""The two-floor site (`irloc serve --demo two-floors`) in-process: every lift ride, how long
after leaving the lift the robot had its first landmark fix on the new floor (told: r2) or
was proposed that floor (not told: r3, the proposal accepted at once, as an operator would),
and every landmark-mode pose that named another floor than the robot was on.

    .venv/bin/python bench/bench_floors.py [--seconds 150] [--seed 11]
"""

from __future__ import annotations

import argparse
import asyncio
import tempfile
from pathlib import Path

import numpy as np

from live.services import SiteServices
from live.settings import Settings
from sim.world import IN_LIFT


async def run(duration_s: float, seed: int) -> None:
    settings = Settings(
        data_dir=Path(tempfile.mkdtemp()), viewer_enabled=False, scenario="two_floors", seed=seed
    )
    services = SiteServices(settings)
    await services.start()
    sim, live = services.sim, services.live
    assert sim is not None and live is not None
    sub = services.robots.subscribe_poses(maxsize=100_000)
    events = services.events.bus.subscribe()
    floor_of = {n: sim.true_floor(n) for n in sim.robot_names}
    left: dict[str, int] = {}  # robot -> site time it left the lift (the truth changed floor)
    told: list[tuple[str, str, float]] = []  # (robot, floor, s from leaving to first fix)
    proposed: list[tuple[str, str, float, bool]] = []  # (robot, floor, s, right floor)
    wrong = {n: 0 for n in sim.robot_names}
    fixes = {n: 0 for n in sim.robot_names}
    errors: list[float] = []
    t_end = services.clock_ns() + int(duration_s * 1e9)
    while services.clock_ns() < t_end:
        await asyncio.sleep(0.05)
        now = services.clock_ns()
        for name in sim.robot_names:
            f = sim.true_floor(name)
            if f != floor_of[name] and not sim.rig(name).robot.in_lift:
                floor_of[name], left[name] = f, now
        for e in events.drain():
            if e.kind == "floor_proposed" and e.robot in left:
                right = e.data["floor"] == sim.true_floor(e.robot)
                proposed.append((e.robot, e.data["floor"], (now - left[e.robot]) / 1e9, right))
                if right and live.floor_watch is not None:
                    live.floor_watch.accept(e.robot, by="bench")
        for u in sub.drain():
            truth_floor = sim.true_floor_at(u.robot, u.t_ns)
            if u.mode != "landmark" or u.x is None or u.y is None or truth_floor in (None, IN_LIFT):
                continue
            fixes[u.robot] += 1
            if u.floor != truth_floor:
                wrong[u.robot] += 1
                continue
            t = sim.true_pose_at(u.robot, u.t_ns)
            if t is not None:
                errors.append(float(np.hypot(u.x - t[0], u.y - t[1])))
            if u.robot in left and u.robot == "r2":
                told.append((u.robot, u.floor, (u.t_ns - left.pop(u.robot)) / 1e9))
    await services.stop()
    print(f"two_floors, seed {seed}, {duration_s:.0f} s of site time")
    for robot, floor, s in told:
        print(f"  {robot} told at the lift: first fix on floor {floor} {s:.2f} s after leaving it")
    for robot, floor, s, right in proposed:
        what = "right" if right else "WRONG"
        print(
            f"  {robot} not told: proposed floor {floor} ({what}) {s:.1f} s after leaving the lift"
        )
    for name in sim.robot_names:
        print(
            f"  {name}: {fixes[name]} landmark poses, {wrong[name]} on another floor than its own"
        )
    if errors:
        err = np.array(errors)
        med, worst = float(np.median(err)) * 100, float(err.max()) * 100
        print(f"  landmark-pose error on the right floor: median {med:.1f} cm, max {worst:.1f} cm")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=150.0)
    p.add_argument("--seed", type=int, default=11)
    args = p.parse_args()
    asyncio.run(run(args.seconds, args.seed))


if __name__ == "__main__":
    main()
