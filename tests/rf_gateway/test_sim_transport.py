"""SimTransport and the Gateway over the virtual site's radio (sim/radio.py, no mocks)."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from lighting.battery import Battery
from localizer.events import LedsChanged
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.config import GatewayConfig
from rf_gateway.errors import LandmarkUnreachableError, RadioTimeout, TransportUnavailable
from rf_gateway.factory import make_transport
from rf_gateway.gateway import Gateway
from rf_gateway.sim_transport import SimTransport
from rf_gateway.transport import DiscoveredRadio
from rf_gateway.xbee_transport import XBeeTransport
from sim.radio import SimRadio
from sim.world import SimLandmark, World

ADDR = {i: f"0013A2004100000{i}" for i in (1, 2, 3, 4)}


def site(loss: float = 0.0, seed: int = 0) -> tuple[World, SimRadio]:
    lms = {
        i: SimLandmark(
            i,
            np.array([i, 0.0, 2.5]),
            np.array([i, 0.0, 2.5]),
            ADDR[i],
            Battery(),
            radio_dead=i == 4,
        )
        for i in ADDR
    }
    world = World(lms)
    radio = SimRadio(
        world,
        rng=np.random.default_rng(seed),
        latency_s=(0.001, 0.003),
        loss=loss,
        timeout_s=0.02,
        discover_s=0.001,
    )
    return world, radio


def test_sim_transport_switches_reads_and_discovers() -> None:
    world, radio = site()

    async def main() -> None:
        t = SimTransport(radio)
        with pytest.raises(TransportUnavailable):
            await t.set_pin(ADDR[1], False)
        await t.open()
        await t.set_pin(ADDR[1].lower(), False)
        assert world.lit_ids() == {2, 3, 4}
        mv = await t.read_supply_mv(ADDR[2])
        assert 3000 < mv < 3200  # fresh cells, about 3.16 V open circuit
        with pytest.raises(RadioTimeout, match=ADDR[4]):
            await t.set_pin(ADDR[4], False)
        assert await t.discover() == [DiscoveredRadio(ADDR[i], f"LM{i}") for i in (1, 2, 3)]
        await t.close()
        assert t.state == "closed"

    asyncio.run(main())
    assert SimTransport(radio).command_timeout_s == pytest.approx(0.22)


def test_gateway_over_lossy_sim_radio_applies_every_state() -> None:
    world, radio = site(loss=0.2, seed=5)
    config = GatewayConfig(
        max_tries=8, retry_backoff_s=0.001, battery=BatteryMonitorConfig(interval_s=None)
    )

    async def main() -> list[LedsChanged]:
        gw = Gateway(SimTransport(radio), {i: ADDR[i] for i in (1, 2, 3)}, config)
        await gw.start()
        sub = gw.subscribe()
        for lit in ([1], [2, 3], [], [1, 2, 3]):
            await gw.set_leds(lit)
            assert world.lit_ids() - {4} == set(lit)
        with pytest.raises(LandmarkUnreachableError, match="landmark 4"):
            gw.update_landmarks(dict(ADDR))
            await gw.led(4, False)
        assert gw.stats.retries > 0
        await gw.close()
        events = []
        while (ev := sub.get_nowait()) is not None:
            events.append(ev)
        return [e for e in events if not e.changing]  # the confirmed states

    events = asyncio.run(main())
    # start() lit every LED first (in the background, ahead of the first request)
    assert events[0].all_lit
    assert [e.lit for e in events[1:4]] == [frozenset({1}), frozenset({2, 3}), frozenset()]
    assert events[4].all_lit


def test_make_transport_builds_the_named_transport() -> None:
    _, radio = site()
    assert isinstance(make_transport("sim", sim_radio=radio), SimTransport)
    xbee = make_transport("xbee:/dev/ttyUSB7@115200", pin="D2")
    assert isinstance(xbee, XBeeTransport)
    assert (xbee.port, xbee.baud, xbee.pin) == ("/dev/ttyUSB7", 115200, "D2")
    with pytest.raises(ValueError, match="sim_radio"):
        make_transport("sim")
