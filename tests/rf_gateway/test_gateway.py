from __future__ import annotations

import asyncio
from collections.abc import Coroutine
from typing import Any, TypeVar

import numpy as np
import pytest

from localizer.events import LedsChanged
from rf_gateway.battery import NS_PER_DAY, BatteryMonitorConfig
from rf_gateway.config import GatewayConfig
from rf_gateway.errors import LandmarkUnreachableError, TransportUnavailable, UnknownLandmarkError
from rf_gateway.events import (
    LandmarkReachable,
    LandmarkUnreachable,
    LowBattery,
    TransportStateChanged,
)
from rf_gateway.gateway import Gateway
from rf_gateway.scheduler import Priority
from rf_gateway.transport import DiscoveredRadio
from tests.rf_gateway.scripted import ScriptedTransport

ADDR = {i: f"0013A2004100{i:04X}" for i in (1, 2, 3, 4)}
FAST = GatewayConfig(
    retry_backoff_s=0.001, light_all_on_start=False, battery=BatteryMonitorConfig(interval_s=None)
)


def make(config: GatewayConfig = FAST) -> tuple[Gateway, ScriptedTransport]:
    transport = ScriptedTransport()
    return Gateway(transport, ADDR, config, clock_ns=transport.clock), transport


T = TypeVar("T")


def run(coro: Coroutine[Any, Any, T]) -> T:
    return asyncio.run(coro)


def test_set_leds_lights_exactly_these_and_stamps_the_last_confirmation() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        sub = gw.subscribe()
        event = await gw.set_leds([2, 3])
        assert tr.pins == {ADDR[1]: False, ADDR[2]: True, ADDR[3]: True, ADDR[4]: False}
        assert event == LedsChanged(4000, lit=frozenset({2, 3}))
        announced = sub.get_nowait()  # before sending: every LED's state is unknown
        assert announced.changing == frozenset({1, 2, 3, 4}) and announced.t_ns < event.t_ns
        assert sub.get_nowait() == event
        # only the changed landmarks are sent again
        tr.log.clear()
        event = await gw.set_leds([1, 2, 3, 4])
        assert sorted(tr.log) == [("pin", ADDR[1], True), ("pin", ADDR[4], True)]
        assert event == LedsChanged(6000, all_lit=True)
        assert gw.stats.skipped == 2
        late = gw.subscribe()
        assert late.get_nowait() == event  # a new subscriber gets the current truth first
        await gw.close()

    run(main())


def test_unknown_landmark_is_named_and_nothing_is_sent() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        with pytest.raises(UnknownLandmarkError, match="unknown landmark id 99"):
            await gw.set_leds([1, 99])
        for call in (gw.led(98, True), gw.blink(97), gw.battery(96)):
            with pytest.raises(KeyError):
                await call
        assert tr.log == []

    run(main())


def test_unreachable_landmark_raises_event_and_the_others_carry_on() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        events = gw.subscribe_events()
        tr.dead.add(ADDR[3])
        with pytest.raises(LandmarkUnreachableError, match=r"landmark 3 .* after 3 tries"):
            await gw.set_leds([1, 2, 3, 4])
        assert tr.pins == {ADDR[1]: True, ADDR[2]: True, ADDR[4]: True}
        assert gw.leds == LedsChanged(3000, lit=frozenset({1, 2, 4}))
        assert gw.unreachable == {3}
        assert [e for e in tr.log if e[1] == ADDR[3]] == [("pin", ADDR[3], True)] * 3
        assert events.get_nowait() == LandmarkUnreachable(3000, 3, ADDR[3], 3)
        with pytest.raises(LandmarkUnreachableError, match="after 1 tries"):
            await gw.led(3, True)  # already unreachable: one probe, not max_tries
        assert len([e for e in tr.log if e[1] == ADDR[3]]) == 4
        assert events.get_nowait() is None  # raised once, not at every failure
        tr.dead.clear()
        await gw.led(3, True)
        assert events.get_nowait() == LandmarkReachable(4000, 3, ADDR[3])
        assert gw.leds == LedsChanged(4000, all_lit=True)

    run(main())


def test_transient_failures_are_retried() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        tr.fail_next[ADDR[2]] = 2
        event = await gw.set_leds([2])
        assert event.lit == frozenset({2})
        assert gw.stats.retries == 2
        assert gw.unreachable == frozenset()

    run(main())


def test_refused_command_is_not_retried() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        tr.refused.add(ADDR[1])
        with pytest.raises(LandmarkUnreachableError, match="status 2"):
            await gw.led(1, True)
        assert len(tr.log) == 1

    run(main())


def test_transport_down_raises_unavailable_without_marking_landmarks() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        events = gw.subscribe_events()
        tr.set_state("reopening")
        assert events.get_nowait() == TransportStateChanged(0, "reopening")
        with pytest.raises(TransportUnavailable):
            await gw.led(1, True)
        assert gw.unreachable == frozenset()

    run(main())


def test_latest_request_wins_per_landmark() -> None:
    async def main() -> None:
        gw, tr = make()
        tr.delay_s = 0.01
        await gw.start()
        async with gw.sweep():
            first = asyncio.create_task(gw.set_leds([1, 2]))
            await asyncio.sleep(0.002)  # the first commands are in flight
            second = asyncio.create_task(gw.set_leds([3]))
            third = asyncio.create_task(gw.set_leds([4]))
            results = await asyncio.gather(first, second, third)
        assert tr.pins == {ADDR[1]: False, ADDR[2]: False, ADDR[3]: False, ADDR[4]: True}
        # each landmark: at most the in-flight command then the newest level (3's skipped)
        per = {a: [h for _, ad, h in tr.log if ad == a] for a in ADDR.values()}
        assert per[ADDR[1]] == [True, False]
        assert per[ADDR[4]] == [False, True]
        assert results[-1].lit == frozenset({4})

    run(main())


def test_sweeps_are_serialised() -> None:
    async def main() -> list[tuple[str, int]]:
        gw, tr = make()
        tr.delay_s = 0.001
        await gw.start()
        steps: list[tuple[str, int]] = []

        async def robot(name: str, ids: list[int]) -> None:
            async with gw.sweep():
                for lid in ids:
                    await gw.set_leds([lid])
                    steps.append((name, lid))
                    await asyncio.sleep(0.002)

        await asyncio.gather(robot("a", [1, 2]), robot("b", [3, 4]), gw.led(1, True))
        return steps

    steps = run(main())
    assert steps in (
        [("a", 1), ("a", 2), ("b", 3), ("b", 4)],
        [("b", 3), ("b", 4), ("a", 1), ("a", 2)],
    )


def test_identification_goes_before_battery_polls() -> None:
    async def main() -> list[tuple[object, ...]]:
        config = GatewayConfig(max_in_flight=1, light_all_on_start=False, battery=FAST.battery)
        gw, tr = make(config)
        tr.delay_s = 0.001
        await gw.start()
        polls = asyncio.create_task(gw.poll_batteries())
        await asyncio.sleep(0)  # 4 battery reads: one in flight, three waiting
        await gw.set_leds([1], priority=Priority.IDENTIFY)
        await polls
        return tr.log

    log = run(main())
    kinds = [entry[0] for entry in log]
    assert kinds == ["mv"] + ["pin"] * 4 + ["mv"] * 3


def test_blink_toggles_and_restores() -> None:
    async def main() -> None:
        config = GatewayConfig(
            blink_count=2, blink_period_s=0.002, light_all_on_start=False, battery=FAST.battery
        )
        gw, tr = make(config)
        await gw.start()
        await gw.set_leds([1, 2, 3, 4])
        tr.log.clear()
        event = await gw.blink(2)
        assert tr.log == [("pin", ADDR[2], v) for v in (False, True, False, True)]
        assert event.all_lit

    run(main())


def test_battery_history_low_event_and_days_left() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        events = gw.subscribe_events()
        for day, mv in enumerate([2600, 2500, 2450, 2400, 2350]):
            tr.clock.now = day * NS_PER_DAY
            tr.supply_mv[ADDR[1]] = mv
            reading = await gw.battery(1)
        # least squares over days 0..4: -60 mV/day, 2340 mV at day 4 -> (2340 - 2100) / 60
        assert reading.days_left is not None
        np.testing.assert_allclose(reading.days_left, 4.0, rtol=1e-6)
        low = events.get_nowait()
        assert isinstance(low, LowBattery)
        assert (low.landmark_id, low.supply_mv) == (1, 2400)
        assert events.get_nowait() is None  # once per crossing
        assert [mv for _, mv in gw.batteries.readings(1)] == [2600, 2500, 2450, 2400, 2350]

    run(main())


def test_discover_lists_only_radios_not_in_the_map() -> None:
    async def main() -> list[DiscoveredRadio]:
        gw, tr = make()
        await gw.start()
        tr.radios = [DiscoveredRadio(ADDR[1], "LM-1"), DiscoveredRadio("0013A20041FFFFFF", "new")]
        return await gw.discover()

    assert run(main()) == [DiscoveredRadio("0013A20041FFFFFF", "new")]


def test_update_landmarks_validates_and_forgets() -> None:
    async def main() -> None:
        gw, _tr = make()
        await gw.start()
        await gw.set_leds([1, 2, 3, 4])
        with pytest.raises(ValueError, match="share radio"):
            gw.update_landmarks({1: ADDR[1], 2: ADDR[1].lower()})
        with pytest.raises(ValueError, match="landmark 7 radio"):
            gw.update_landmarks({7: "xyz"})
        gw.update_landmarks({1: ADDR[1], 2: ADDR[2]})
        assert gw.landmarks == {1: ADDR[1], 2: ADDR[2]}
        event = await gw.set_leds([1, 2])
        assert event.all_lit
        with pytest.raises(UnknownLandmarkError):
            await gw.led(3, False)

    run(main())


def test_close_answers_pending_callers() -> None:
    async def main() -> None:
        gw, tr = make()
        tr.delay_s = 10.0  # a command that would never come back in time
        await gw.start()
        pending = asyncio.create_task(gw.led(1, False))
        await asyncio.sleep(0.01)
        await gw.close()
        with pytest.raises(TransportUnavailable, match="closed"):
            await pending

    run(main())


def test_same_level_requested_while_in_flight_is_sent_once() -> None:
    async def main() -> list[tuple[object, ...]]:
        gw, tr = make()
        tr.delay_s = 0.01
        await gw.start()
        async with gw.sweep():
            first = asyncio.create_task(gw.led(2, True))
            await asyncio.sleep(0.002)
            events = await asyncio.gather(first, gw.led(2, True))
        assert events[0] == events[1] == LedsChanged(1000, lit=frozenset({2}))
        return tr.log

    assert run(main()) == [("pin", ADDR[2], True)]


def test_start_lights_everything_before_any_request() -> None:
    async def main() -> tuple[list[LedsChanged | None], list[tuple[object, ...]]]:
        transport = ScriptedTransport(dead={ADDR[4]})
        config = GatewayConfig(retry_backoff_s=0.001, battery=FAST.battery)
        gw = Gateway(transport, ADDR, config, clock_ns=transport.clock)
        sub = gw.subscribe()
        await gw.start()
        with pytest.raises(LandmarkUnreachableError, match="landmark 4"):
            await gw.set_leds([2])  # waits for the start-up lighting, then applies
        events = [sub.get_nowait() for _ in range(4)]
        await gw.close()
        return [e for e in events if not e.changing], transport.log

    events, log = run(main())
    assert events == [
        LedsChanged(3000, lit=frozenset({1, 2, 3})),
        LedsChanged(5000, lit=frozenset({2})),
    ]
    assert log[:3] == [("pin", ADDR[i], True) for i in (1, 2, 3)]


def test_set_awake_time_sends_st_to_each_landmark_and_skips_one_that_fails() -> None:
    async def main() -> None:
        gw, tr = make()
        await gw.start()
        tr.dead.add(ADDR[3])
        done = await gw.set_awake_time([1, 2, 3], 30.0)
        assert done == frozenset({1, 2})
        assert sorted(e for e in tr.log if e[0] == "st" and e[2] == 30.0)[:2] == [
            ("st", ADDR[1], 30.0), ("st", ADDR[2], 30.0),
        ]  # fmt: skip
        assert 3 in gw.unreachable
        with pytest.raises(UnknownLandmarkError, match="99"):
            await gw.set_awake_time([1, 99], 1.0)
        await gw.close()

    run(main())
