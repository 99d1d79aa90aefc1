"""The live site loop with LED control, run offline faster than real time.

The same parts as `irloc serve` on its simulated site, without HTTP and threads: the
`sim.virtual_site.VirtualSite` (robots, world, `SimRadio`), the RF gateway on the simulated
transport (`rf_gateway.Gateway` + `SimTransport`), the server's `LedCoordinator` that applies the
localizer's `LedRequest`s and forwards every confirmed `LedsChanged`, and one `Localizer`.
They run on an asyncio loop whose clock is *virtual*: whenever nothing is ready, the loop
jumps to its next timer instead of sleeping (radio latencies, timeouts and retries keep
their simulated durations, they just take no wall time). The site is stepped every
`step_s` of that clock, as the server's clock thread steps it.
"""

from __future__ import annotations

import asyncio
import dataclasses
import selectors
from collections.abc import Mapping
from typing import Any

from bench.robustness_score import FrameResult
from live.leds.coordinator import LedCoordinator
from localizer.config import LocalizerConfig
from localizer.events import (
    Event,
    LedRequest,
    LedsChanged,
    NoPose,
    OdometryMeasured,
    PoseEstimate,
)
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.config import GatewayConfig
from rf_gateway.gateway import Gateway
from rf_gateway.sim_transport import SimTransport
from sim.scenario import Scenario
from sim.virtual_site import VirtualSite

NS = 1_000_000_000


class _Clock:
    def __init__(self) -> None:
        self.now_s = 0.0

    def time(self) -> float:
        return self.now_s

    def ns(self) -> int:
        return round(self.now_s * NS)


class _FastForwardSelector(selectors.BaseSelector):
    """A selector that never blocks: when nothing is ready it moves the clock on by the
    timeout the loop asked for (the time to its next timer)."""

    def __init__(self, clock: _Clock) -> None:
        self._inner = selectors.DefaultSelector()
        self._clock = clock

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._inner.register(fileobj, events, data)

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._inner.unregister(fileobj)

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._inner.modify(fileobj, events, data)

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        ready = self._inner.select(0)
        if not ready:
            if timeout is None:
                raise RuntimeError("virtual-time loop: nothing scheduled and nothing ready")
            self._clock.now_s += max(timeout, 0.0)
        return ready

    def get_map(self) -> Mapping[Any, selectors.SelectorKey]:
        return self._inner.get_map()

    def close(self) -> None:
        self._inner.close()


def virtual_time_loop() -> tuple[asyncio.AbstractEventLoop, _Clock]:
    """A new event loop on a virtual clock (starting at 0 s) and that clock."""
    clock = _Clock()
    loop = asyncio.SelectorEventLoop(_FastForwardSelector(clock))
    loop.time = clock.time  # type: ignore[method-assign]
    return loop, clock


@dataclasses.dataclass
class _Inbox:
    """What the LED coordinator forwards to the robot (its `RobotRunner.post`)."""

    events: list[LedsChanged] = dataclasses.field(default_factory=list)

    def post(self, event: LedsChanged) -> None:
        self.events.append(event)


@dataclasses.dataclass
class LiveRun:
    """A live run's outputs, with the truth at each frame and the kidnaps (loop time)."""

    results: list[FrameResult]
    truth: dict[int, tuple[float, float, float]]
    kidnaps: list[tuple[int, int]]
    t_start_ns: int
    site: VirtualSite
    led_requests: int


async def _run(
    site: VirtualSite,
    name: str,
    clock: _Clock,
    duration_s: float,
    step_s: float,
    config: LocalizerConfig | None,
) -> LiveRun:
    records = site.landmark_records()
    addresses = {int(str(r["id"])): str(r["radio"]) for r in records}
    gateway = Gateway(
        SimTransport(site.radio),
        addresses,
        GatewayConfig(battery=BatteryMonitorConfig(interval_s=None)),
        clock_ns=clock.ns,
    )
    await gateway.start()
    inbox = _Inbox()
    coordinator = LedCoordinator(gateway, lambda: [inbox])  # type: ignore[list-item]
    coordinator.start()
    loc = Localizer(
        site.camera(name), LandmarkMap.from_records(records), site.robot_geometry(name), config
    )
    results: list[FrameResult] = []
    truth: dict[int, tuple[float, float, float]] = {}
    requests = 0
    site.step(clock.ns())
    t_start = clock.ns()
    end = t_start + round(duration_s * NS)
    try:
        while clock.ns() < end:
            await asyncio.sleep(step_s)
            due: list[tuple[int, int, Event]] = [(e.t_ns, 0, e) for e in inbox.events]
            inbox.events.clear()
            due += [(s.event.t_ns, 1, s.event) for s in site.step(clock.ns())]
            for _, _, event in sorted(due, key=lambda x: (x[0], x[1])):
                for out in loc.handle(event):
                    if isinstance(out, LedRequest):
                        requests += 1
                        coordinator.request(name, out)
                    elif isinstance(out, PoseEstimate):
                        pose = (out.x, out.y, out.theta)
                        results.append(FrameResult(out.t_ns, pose, out.mode, out.landmark_ids))
                    elif isinstance(out, NoPose):
                        results.append(FrameResult(out.t_ns, None, out.mode))
                if not isinstance(event, OdometryMeasured | LedsChanged):
                    t = site.true_pose_at(name, event.t_ns)
                    if t is not None:
                        truth[event.t_ns] = t
    finally:
        await coordinator.stop()
        await gateway.close()
    kidnaps = [(a + t_start, b + t_start) for a, b in site.rig(name).robot.kidnaps]
    return LiveRun(results, truth, kidnaps, t_start, site, requests)


def run_live(
    scenario: Scenario,
    *,
    robot: str | None = None,
    seed: int | None = None,
    duration_s: float,
    step_s: float = 0.01,
    config: LocalizerConfig | None = None,
) -> LiveRun:
    """Run one robot of `scenario` on the live site loop with LED control, on virtual time.

    Args:
        scenario: the site (only the robot `robot`, default the first, is kept).
        seed: overrides the scenario's seed.
        duration_s: simulated seconds.
        step_s: how often the site is stepped, simulated seconds.
        config: the localizer's tuning.
    """
    name = robot or scenario.robots[0].name
    sc = dataclasses.replace(scenario, robots=tuple(r for r in scenario.robots if r.name == name))
    if not sc.robots:
        raise ValueError(
            f"unknown robot {name!r}; the scenario has {[r.name for r in scenario.robots]}"
        )
    loop, clock = virtual_time_loop()
    try:
        site = VirtualSite(sc, seed=seed, clock_ns=clock.ns)
        return loop.run_until_complete(_run(site, name, clock, duration_s, step_s, config))
    finally:
        loop.close()
