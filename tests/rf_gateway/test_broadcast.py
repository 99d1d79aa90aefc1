"""The start-up sweep of sleeping landmarks by broadcast (rf_gateway/gateway.py with
sim/radio.py): LED on and the wake window's `ST` as one frame each, the LEDs believed lit
at once and read back one by one, a landmark that missed the broadcast switched on."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from bench.virtual_site import run_virtual
from lighting.battery import Battery
from lighting.energy import RadioSleep
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.config import GatewayConfig, SleepConfig
from rf_gateway.gateway import Gateway
from rf_gateway.sim_transport import SimTransport
from sim.radio import SimRadio
from sim.world import SimLandmark, World

N = 30
SP = 0.5


def _site(*, loss: float, dead: int | None = None) -> tuple[World, SimRadio, dict[int, str]]:
    landmarks = {
        i: SimLandmark(i, np.zeros(3), np.zeros(3), f"0013A200410000{i:02X}", Battery(),
                       radio_dead=i == dead, led_on=False)
        for i in range(1, N + 1)
    }  # fmt: skip
    world = World(landmarks)
    radio = SimRadio(world, rng=np.random.default_rng(3), loss=loss, sleep=RadioSleep(SP))
    return world, radio, {i: lm.address for i, lm in landmarks.items()}


def _gateway(radio: SimRadio, addresses: dict[int, str], start_awake_s: float | None) -> Gateway:
    config = GatewayConfig(
        sleep=SleepConfig(SP),
        start_awake_s=start_awake_s,
        battery=BatteryMonitorConfig(interval_s=None),
    )
    return Gateway(SimTransport(radio), addresses, config, clock_ns=lambda: 0)


async def _start(gw: Gateway, settle_s: float) -> float:
    """Start; seconds until the LED state is published as known (the sweep lock free)."""
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await gw.start()
    async with gw.sweep():
        took = loop.time() - t0
    await asyncio.sleep(settle_s)  # the read-back runs on
    return took


def test_the_start_up_sweep_is_two_broadcasts_and_every_led_is_read_back() -> None:
    """30 sleeping landmarks: lit and published within one sleep period and an air time
    (one command each through four slots, each waiting for its wake-up, takes about
    30 x 0.3 s / 4 = 2.2 s), `ST` 30 s on every one, then each pin read back once."""
    world, radio, addresses = _site(loss=0.0)

    async def main() -> tuple[float, Gateway]:
        gw = _gateway(radio, addresses, 30.0)
        assert gw.start_awake_s == 30.0
        took = await _start(gw, 3.0)
        await gw.close()
        return took, gw

    took, gw = run_virtual(main())
    assert took <= SleepConfig(SP).broadcast_wait_s + 0.01
    assert all(lm.led_on for lm in world.landmarks.values())
    assert all(radio.wake_s(i) == 30.0 for i in addresses)
    assert gw.stats.broadcasts == 2 and gw.stats.broadcast_missed == 0
    assert gw.stats.commands == 2 + N  # the broadcasts and one read-back each
    assert gw.leds is not None and gw.leds.all_lit and not gw.leds.changing


def test_a_landmark_that_missed_the_broadcast_is_found_dark_and_switched_on() -> None:
    world, radio, addresses = _site(loss=0.15, dead=4)

    async def main() -> Gateway:
        gw = _gateway(radio, addresses, 30.0)
        await _start(gw, 8.0)
        await gw.close()
        return gw

    gw = run_virtual(main())
    assert all(lm.led_on for i, lm in world.landmarks.items() if i != 4)
    assert gw.stats.broadcast_missed >= 1  # 15 % loss: some missed the LED broadcast
    assert gw.unreachable == frozenset({4})
    assert gw.leds is not None and gw.leds.lit == frozenset(addresses) - {4}


def test_without_a_start_up_window_the_sweep_sends_one_command_per_landmark() -> None:
    world, radio, addresses = _site(loss=0.0)

    async def main() -> tuple[float, Gateway]:
        gw = _gateway(radio, addresses, None)
        assert gw.start_awake_s is None
        took = await _start(gw, 0.0)
        await gw.close()
        return took, gw

    took, gw = run_virtual(main())
    assert gw.stats.commands == N and gw.stats.broadcasts == 0
    assert all(lm.led_on for lm in world.landmarks.values())
    assert took > 1.5  # 30 landmarks through four slots, each waiting for its wake-up
    assert radio.wake_s(1) == pytest.approx(RadioSleep(SP).wake_s)
