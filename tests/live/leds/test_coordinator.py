"""The LED coordinator (live/leds/coordinator.py) over a real gateway and the virtual radio."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

import numpy as np

from lighting.battery import Battery
from live.leds.coordinator import LedCoordinator
from localizer.events import Event, LedRequest, LedsChanged
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.config import GatewayConfig
from rf_gateway.gateway import Gateway
from rf_gateway.sim_transport import SimTransport
from sim.radio import SimRadio
from sim.world import SimLandmark, World

ADDR = {i: f"0013A2004100000{i}" for i in (1, 2, 3, 4)}
ALL = set(ADDR)


class Inbox:
    """A robot's event inbox (what `RobotRunner.post` receives)."""

    def __init__(self) -> None:
        self.events: list[Event] = []

    def post(self, event: Event) -> None:
        self.events.append(event)

    def states(self) -> list[set[int]]:
        """The confirmed LED states received, in order."""
        return [
            ALL if e.all_lit else set(e.lit)
            for e in self.events
            if isinstance(e, LedsChanged) and not e.changing
        ]


def run_site(body: Callable[[LedCoordinator, World, Inbox], Awaitable[None]], **kw: float) -> None:
    lms = {
        i: SimLandmark(i, np.array([i, 0.0, 2.5]), np.array([i, 0.0, 2.5]), ADDR[i], Battery())
        for i in ADDR
    }
    world = World(lms)
    radio = SimRadio(world, rng=np.random.default_rng(1), latency_s=(0.001, 0.002), loss=0.0)

    async def main() -> None:
        gw = Gateway(
            SimTransport(radio), ADDR, GatewayConfig(battery=BatteryMonitorConfig(interval_s=None))
        )
        await gw.start()
        inbox = Inbox()
        coord = LedCoordinator(gw, lambda: [inbox], **kw)  # type: ignore[list-item]
        coord.start()
        try:
            await gw.set_leds(ALL)
            await body(coord, world, inbox)
        finally:
            await coord.stop()
            await gw.close()

    asyncio.run(main())


async def settle(coord: LedCoordinator, s: float = 0.05) -> None:
    for _ in range(200):
        await asyncio.sleep(s / 10)
        if not coord.waiting and coord.gateway.leds is not None and not coord.gateway.leds.changing:
            await asyncio.sleep(s)
            return


def test_a_darken_probe_darkens_that_landmark_alone_and_every_robot_sees_it() -> None:
    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.request("r1", LedRequest(all_lit=True, dark=frozenset({3})))
        await settle(coord)
        assert world.lit_ids() == {1, 2, 4}
        assert inbox.states()[-1] == {1, 2, 4}
        coord.request("r1", LedRequest(all_lit=True))
        await settle(coord)
        assert world.lit_ids() == ALL

    run_site(body, dwell_s=0.01)


def test_requests_of_several_robots_are_applied_in_turn_latest_wins() -> None:
    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.request("r1", LedRequest(all_lit=True, dark=frozenset({1})))
        coord.request("r2", LedRequest(all_lit=True, dark=frozenset({2})))
        coord.request("r2", LedRequest(all_lit=True, dark=frozenset({4})))  # replaces {2}
        await asyncio.sleep(0.005)
        await settle(coord, 0.1)
        assert inbox.states()[-2:] == [ALL - {1}, ALL - {4}]
        assert ALL - {2} not in inbox.states()

    run_site(body, dwell_s=0.03)


def test_held_leds_keep_requests_waiting_until_released() -> None:
    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.hold(True)
        await coord.gateway.set_leds({2})  # the wizard lights one landmark alone
        coord.request("r1", LedRequest(all_lit=True, dark=frozenset({1})))
        await asyncio.sleep(0.1)
        assert world.lit_ids() == {2} and coord.waiting == 1
        coord.hold(False)
        await settle(coord)
        assert world.lit_ids() == ALL - {1}

    run_site(body, dwell_s=0.01)


def test_a_probe_left_behind_is_undone_after_the_idle_time() -> None:
    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.request("r1", LedRequest(all_lit=True, dark=frozenset({2})))
        await settle(coord)
        assert world.lit_ids() == ALL - {2}
        await asyncio.sleep(0.3)  # r1 went away without relighting
        assert world.lit_ids() == ALL

    run_site(body, dwell_s=0.01, idle_restore_s=0.15)


def test_failures_are_reported_once_not_per_request() -> None:
    """An identifying robot sends a request every few frames: a landmark whose radio is dead
    is the gateway's one `landmark_unreachable` report, not one error per request; another
    failure is reported once per quiet time."""
    from rf_gateway.errors import RfGatewayError

    reports: list[tuple[str, str]] = []

    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.on_error = lambda robot, msg: reports.append((robot, msg))
        world.landmarks[3].radio_dead = True
        for probe in (3, 1, 3, 2):  # darkening 3 fails (it stays lit); the others work
            coord.request("r1", LedRequest(all_lit=True, dark=frozenset({probe})))
            await settle(coord)
        assert coord.failures == 2 and reports == []
        assert {1, 4} <= world.lit_ids() and 2 not in world.lit_ids()

        async def link_down(lit: object) -> LedsChanged:
            raise RfGatewayError("radio link down")

        coord.gateway.set_leds = link_down  # type: ignore[method-assign, assignment]
        for probe in (1, 2, 4):
            coord.request("r2", LedRequest(all_lit=True, dark=frozenset({probe})))
            await settle(coord)
        assert reports == [("r2", "radio link down")]

    run_site(body, dwell_s=0.01)
