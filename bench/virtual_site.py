"""A live site on virtual time, for benchmarks that must run a shift faster than real time.

The same parts as `irloc serve` (the virtual site, `SimRadio` through `SimTransport`, the
`Gateway`, the `LedCoordinator`, one `RobotRunner` and localizer per robot, the LED
scheduler), on an asyncio loop whose clock jumps to the next timer whenever nothing is ready:
radio latencies, sleep periods, dwell times and plan periods all pass in virtual time, and
the wall time is only what the code costs. The camera reports spots (`observe="spots"`), not
rendered frames.
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import math
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from lighting.energy import LandmarkEnergy
from live.leds.coordinator import LedCoordinator
from live.leds.runtime import LedScheduler
from live.leds.wiring import (
    gateway_config,
    localizer_config,
    make_scheduler,
    radio_sleep,
)
from live.poses import PoseUpdate
from live.robots import RobotRunner, make_localizer
from live.settings import Settings
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from rf_gateway.gateway import Gateway
from rf_gateway.sim_transport import SimTransport
from sim.routes import Route, Wait
from sim.scenario import Scenario, load_scenario
from sim.virtual_site import VirtualSite

T = TypeVar("T")
STEP_S = 0.01


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """An event loop whose `time()` is virtual: when no callback is ready and no work handed
    to a thread (`run_in_executor`, `asyncio.to_thread`) is still running, it jumps to the
    earliest timer (so `asyncio.sleep(5)` takes no wall time). While a thread works, virtual
    time stands still, as if the work took none: a loaded machine slows the run, never
    what it computes (the LED planner's thread cannot fall behind the site)."""

    def __init__(self) -> None:
        super().__init__()
        self._virtual_s = 0.0
        self._in_flight = 0  # executor work not yet landed back on the loop

    def time(self) -> float:
        return self._virtual_s

    def run_in_executor(  # type: ignore[override]
        self, executor: Any, func: Any, *args: Any
    ) -> asyncio.Future[Any]:
        future = super().run_in_executor(executor, func, *args)
        self._in_flight += 1
        future.add_done_callback(self._landed)
        return future

    def _landed(self, _future: asyncio.Future[Any]) -> None:
        self._in_flight -= 1

    def _run_once(self) -> None:
        ready: collections.deque[Any] = self._ready  # type: ignore[attr-defined]
        scheduled: list[Any] = self._scheduled  # type: ignore[attr-defined]
        if not ready and scheduled and not self._in_flight:
            head = (
                min(h for h in scheduled if not h.cancelled())
                if any(not h.cancelled() for h in scheduled)
                else None
            )
            if head is not None:
                self._virtual_s = max(self._virtual_s, head.when())
        super()._run_once()  # type: ignore[misc]


def run_virtual(coro: Coroutine[Any, Any, T]) -> T:
    """Run a coroutine to completion on a fresh `VirtualTimeLoop`."""
    loop = VirtualTimeLoop()
    try:
        return loop.run_until_complete(coro)
    finally:
        loop.close()


def parked(scenario: Scenario, seconds: float) -> Scenario:
    """The scenario with every robot standing at its start for `seconds` (an idle site)."""
    robots = tuple(dataclasses.replace(r, route=Route((Wait(seconds),))) for r in scenario.robots)
    return dataclasses.replace(scenario, robots=robots)


@dataclass
class SiteRun:
    """What one virtual run saw.

    Attributes:
        poses: every pose update with the truth at its frame, (update, (x, y, theta) | None).
        lit_samples: number of lit landmarks at each 0.25 s sample.
        commands: radio commands the gateway sent.
        seconds: virtual time measured (from `measure_from_s`).
        energy: per landmark, what it did and drew over the run (`lighting.energy`).
        landmark_ids: the site's landmarks.
        scheduler: the scheduler, if any (its books).
    """

    poses: dict[str, list[tuple[PoseUpdate, tuple[float, float, float] | None]]]
    lit_samples: list[int] = field(default_factory=list)
    commands: int = 0
    seconds: float = 0.0
    energy: dict[int, LandmarkEnergy] = field(default_factory=dict)
    landmark_ids: list[int] = field(default_factory=list)
    scheduler: LedScheduler | None = None
    capacity_mah: dict[int, float] = field(default_factory=dict)
    """Charge left in each landmark's cells at the start, mAh."""
    t0_ns: int = 0
    """The site clock at the start."""
    measure_from_s: float = 0.0


async def run_site(
    scenario: Scenario | str,
    settings: Settings,
    seconds: float,
    *,
    seed: int | None = None,
    measure_from_s: float = 0.0,
    known_poses: bool = False,
    on_step: Callable[[float, VirtualSite], None] | None = None,
    routes: bool = True,
    until_fixed: bool = False,
) -> SiteRun:
    """Run a site for `seconds` of virtual time with the settings' LED policy and radios.

    Energy, lit samples and radio commands are counted from `measure_from_s` on (poses from
    the start). `known_poses`: each robot starts with its pose known to within a few
    centimetres (as at the end of a shift) instead of a cold start. `routes`: the scheduler
    knows each robot's route (the next waypoints, as a fleet manager would). `until_fixed`:
    stop early once every robot has had a pose (a cold start's first fixes)."""
    loop = asyncio.get_running_loop()
    sc = load_scenario(scenario) if isinstance(scenario, str) else scenario

    def clock_ns() -> int:
        return round(loop.time() * 1e9)

    site = VirtualSite(
        sc,
        seed=seed,
        clock_ns=clock_ns,
        radio_sleep=radio_sleep(settings),
        observe="spots",
        max_frame_lag_s=10.0,
    )
    records = site.landmark_records()
    lmap = LandmarkMap.from_records(records)
    gateway = Gateway(
        SimTransport(site.radio),
        {int(str(r["id"])): str(r["radio"]) for r in records},
        gateway_config(settings),
        clock_ns=clock_ns,
    )
    runners: dict[str, RobotRunner] = {}
    run = SiteRun({name: [] for name in site.robot_names})
    run.landmark_ids = [int(str(r["id"])) for r in records]
    run.capacity_mah = {
        lid: lm.battery.config.capacity_mah * (1.0 - lm.battery.drawn_fraction)
        for lid, lm in site.world.landmarks.items()
    }

    fixed: set[str] = set()

    def publish(upd: PoseUpdate) -> None:
        run.poses[upd.robot].append((upd, site.true_pose_at(upd.robot, upd.t_ns)))
        if upd.x is not None:
            fixed.add(upd.robot)

    leds = LedCoordinator(gateway, lambda: list(runners.values()))
    for name in site.robot_names:
        cam, geo = site.camera(name), site.robot_geometry(name)
        runners[name] = RobotRunner(
            name,
            cam,
            geo,
            make_localizer(cam, lmap, geo, localizer_config(settings)),
            publish=publish,
            request_leds=leds.request,
        )
    if known_poses:
        rng = np.random.default_rng(0 if seed is None else seed)
        for name, runner in runners.items():
            x, y, th = site.true_pose(name)
            dx, dy = rng.normal(0.0, 0.02, 2)
            localizer = runner.localizer
            assert isinstance(localizer, Localizer)  # `make_localizer`'s
            localizer.set_initial_pose(x + dx, y + dy, th, clock_ns())
    await gateway.start()
    leds.start()
    ids = [int(i) for i in lmap.ids]
    positions = np.asarray(lmap.positions, dtype=np.float64)
    if settings.led_policy == "scheduled":
        run.scheduler = make_scheduler(
            lambda: (ids, positions),
            lambda: list(runners.values()),
            leds,
            clock_ns,
            settings,
            routes=site.planned_route if routes else None,
        )
    t0 = loop.time()
    run.t0_ns, run.measure_from_s = clock_ns(), measure_from_s
    site.step(clock_ns())
    if site.world.energy is not None:
        site.world.energy.reset()
    next_sample = t0 + measure_from_s
    measuring = measure_from_s <= 0
    commands0 = 0
    while (now := loop.time()) - t0 < seconds:
        await asyncio.sleep(STEP_S)
        for sample in site.step(clock_ns()):
            runners[sample.robot].handle(sample.event)
        if not measuring and now - t0 >= measure_from_s:
            measuring = True
            commands0 = gateway.stats.commands
            if site.world.energy is not None:
                site.world.energy.reset()
        if measuring and now >= next_sample:
            run.lit_samples.append(len(site.world.lit_ids()))
            next_sample += 0.25
        if on_step is not None:
            on_step(now - t0, site)
        if until_fixed and len(fixed) == len(run.poses):
            break
    run.seconds = loop.time() - t0 - measure_from_s
    run.commands = gateway.stats.commands - commands0
    if site.world.energy is not None:
        run.energy = {lid: dataclasses.replace(e) for lid, e in site.world.energy.landmarks.items()}
    if run.scheduler is not None:
        await run.scheduler.stop()
    await leds.stop()
    await gateway.close()
    return run


def steady_frames(
    run: SiteRun, name: str, *, settle_s: float = 10.0
) -> tuple[list[str], list[float], float, float]:
    """Per robot, its steady state (frames from `measure_from_s`, or from `settle_s` after its
    first fix when that came later): each frame's mode, the position errors (cm) of the
    frames with a pose, the first fix from the start (s; nan: none) and where the steady
    state began (s; nan: no fix)."""
    rows = run.poses[name]
    first = next((u.t_ns for u, _ in rows if u.x is not None), None)
    if not rows or first is None:
        return [], [], math.nan, math.nan
    first_s = (first - run.t0_ns) * 1e-9
    from_s = max(run.measure_from_s, first_s + settle_s)
    steady = [(u, tr) for u, tr in rows if (u.t_ns - run.t0_ns) * 1e-9 >= from_s]
    err = [
        100 * math.hypot(u.x - tr[0], u.y - tr[1])
        for u, tr in steady
        if u.x is not None and u.y is not None and tr is not None
    ]
    return [u.mode for u, _ in steady], err, first_s, from_s


def robot_stats(run: SiteRun, name: str, *, settle_s: float = 10.0) -> dict[str, float]:
    """Per robot: time to the first fix from the start (s); over its steady state
    (`steady_frames`): share of frames in landmark mode, p95 position error (cm), and where
    that began (s)."""
    modes, err, first_s, from_s = steady_frames(run, name, settle_s=settle_s)
    return {
        "landmark": sum(m == "landmark" for m in modes) / max(len(modes), 1),
        "p95_cm": float(np.percentile(err, 95)) if err else math.nan,
        "first_fix_s": first_s,
        "from_s": from_s,
    }
