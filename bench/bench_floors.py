"""Robots changing floors on the two-floor site (`irloc serve --demo two-floors`), in-process
and live: for every lift ride, how long after leaving the lift the robot was localized on
its new floor, and how many wrong poses went out meanwhile.

- r2 is told its floor when it leaves the lift (its fleet manager): seconds from leaving
  to its first landmark fix on the new floor.
- r3 is not told: seconds from leaving to its floor being marked unknown (its poses
  withheld), to the right floor being proposed (accepted at once, as an operator or the
  fleet would), and to its first landmark fix there.
- A wrong pose is one that names another floor than the robot is on (the truth; in the
  cabin a robot is on no floor and nothing is counted): with a position, in any mode
  (landmark fixes and dead reckoning alike).
- A pose withheld (floor unknown) is *right* when the robot is not on the floor the site
  has it on, *needless* when it is (a pose that would have been true was not served).

The site carries its scenario's realistic errors (each robot's calibration residual, wheel
radius and base errors, survey error). Figures are per ride; the totals at the end.

    .venv/bin/python bench/bench_floors.py [--seconds 300] [--seed 11]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from live.services import SiteServices
from live.settings import Settings
from sim.world import IN_LIFT


@dataclass
class Ride:
    """One robot's lift ride, from the moment it left the cabin."""

    robot: str
    to: str
    left_ns: int
    unknown_s: float | None = None
    proposed_s: float | None = None
    proposed_right: bool | None = None
    fixed_s: float | None = None
    wrong_landmark: int = 0
    wrong_other: int = 0
    withheld: int = 0
    needless: int = 0
    errors_cm: list[float] = field(default_factory=list)

    def after(self, t_ns: int) -> float:
        return (t_ns - self.left_ns) / 1e9


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.2f}"


async def run(duration_s: float, seed: int) -> list[Ride]:
    settings = Settings(
        data_dir=Path(tempfile.mkdtemp()), viewer_enabled=False, scenario="two_floors", seed=seed
    )
    services = SiteServices(settings)
    await services.start()
    sim, live = services.virtual_site, services.runner
    assert sim is not None and live is not None
    sub = services.robots.subscribe_poses(maxsize=100_000)
    events = services.events.bus.subscribe()
    on_floor = {n: sim.true_floor(n) for n in sim.robot_names}
    rides: list[Ride] = []
    current: dict[str, Ride] = {}
    wrong_outside = 0  # wrong poses not after a ride (none expected)
    needless = {n: 0 for n in sim.robot_names}  # withheld on the floor the site has it on
    served = {n: 0 for n in sim.robot_names}  # poses with a position
    t_end = services.clock_ns() + int(duration_s * 1e9)
    while services.clock_ns() < t_end:
        await asyncio.sleep(0.05)
        for u in sub.drain():
            truth = sim.true_floor_at(u.robot, u.t_ns)
            if truth is None or truth == IN_LIFT:
                continue
            if truth != on_floor[u.robot]:  # the first frame out of the cabin
                on_floor[u.robot] = truth
                current[u.robot] = ride = Ride(u.robot, truth, u.t_ns)
                rides.append(ride)
            ride_now = current.get(u.robot)
            if u.floor_unknown:
                if u.floor == truth:
                    needless[u.robot] += 1
                if ride_now is not None:
                    ride_now.withheld += 1
                    ride_now.needless += u.floor == truth
                    if ride_now.unknown_s is None and u.floor != truth:
                        ride_now.unknown_s = ride_now.after(u.t_ns)
                continue
            if u.x is None or u.y is None:
                continue
            served[u.robot] += 1
            if u.floor != truth:
                if ride_now is None:
                    wrong_outside += 1
                elif u.mode == "landmark":
                    ride_now.wrong_landmark += 1
                else:
                    ride_now.wrong_other += 1
                continue
            if ride_now is None or u.mode != "landmark":
                continue
            if ride_now.fixed_s is None:
                ride_now.fixed_s = ride_now.after(u.t_ns)
            t = sim.true_pose_at(u.robot, u.t_ns)
            if t is not None:
                ride_now.errors_cm.append(float(np.hypot(u.x - t[0], u.y - t[1])) * 100)
        for e in events.drain():
            ride_now = current.get(e.robot or "")
            if e.kind != "floor_proposed" or ride_now is None or ride_now.proposed_s is not None:
                continue
            ride_now.proposed_s = ride_now.after(services.clock_ns())
            ride_now.proposed_right = e.data["floor"] == ride_now.to
            if ride_now.proposed_right and live.floor_watch is not None:
                live.floor_watch.accept(e.robot or "", by="bench")
    await services.stop()
    if wrong_outside:
        print(f"  {wrong_outside} wrong poses outside any ride")
    for name in sim.robot_names:
        print(f"  {name}: {served[name]} poses served, {needless[name]} withheld needlessly")
    return rides


def report(rides: list[Ride], seed: int, duration_s: float) -> None:
    print(f"two_floors, seed {seed}, {duration_s:.0f} s of site time, {len(rides)} rides")
    print(
        "  robot  to  unknown_s  proposed_s  fixed_s  wrong(landmark)  wrong(other)  "
        "withheld (needless)  err_med_cm"
    )
    for r in rides:
        med = f"{statistics.median(r.errors_cm):.1f}" if r.errors_cm else "-"
        right = "" if r.proposed_right in (None, True) else " WRONG FLOOR"
        print(
            f"  {r.robot:5}  {r.to:>2}  {_fmt(r.unknown_s):>9}  {_fmt(r.proposed_s):>10}"
            f"  {_fmt(r.fixed_s):>7}  {r.wrong_landmark:>15}  {r.wrong_other:>12}"
            f"  {r.withheld:>8} ({r.needless:>4})  {med:>10}{right}"
        )
    for robot in sorted({r.robot for r in rides}):
        mine = [r for r in rides if r.robot == robot]
        fixed = [r.fixed_s for r in mine if r.fixed_s is not None]
        print(
            f"  {robot}: {len(mine)} rides, fixed on the new floor in {len(fixed)}"
            f" (median {_fmt(statistics.median(fixed) if fixed else None)} s, max"
            f" {_fmt(max(fixed) if fixed else None)} s), wrong poses: "
            f"{sum(r.wrong_landmark for r in mine)} landmark, "
            f"{sum(r.wrong_other for r in mine)} other; withheld (floor unknown): "
            f"{sum(r.withheld for r in mine)}"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=300.0)
    p.add_argument("--seed", type=int, default=11)
    args = p.parse_args()
    rides = asyncio.run(run(args.seconds, args.seed))
    report(rides, args.seed, args.seconds)


if __name__ == "__main__":
    main()
