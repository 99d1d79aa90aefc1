from __future__ import annotations

import asyncio

import numpy as np
import pytest

from lighting.battery import Battery, BatteryConfig, cell_voltage
from sim.radio import SimRadio
from sim.world import SimLandmark, World


def test_battery_discharges_monotonically_and_led_dims_then_dies() -> None:
    battery = Battery(charge=0.2)
    volts, brightness = [], []
    for _ in range(400):
        volts.append(battery.supply_v(True))
        brightness.append(battery.led_brightness())
        battery.advance(600.0, led_on=True)
    volts_a, bright_a = np.array(volts), np.array(brightness)
    assert np.all(np.diff(volts_a[bright_a > 0]) <= 1e-12)
    assert np.all(np.diff(bright_a) <= 1e-12)
    assert 0.4 < bright_a[0] < 0.7  # 80 % drawn: 2.32 V left
    assert bright_a[-1] == 0.0
    assert not battery.alive


def test_fresh_battery_values() -> None:
    battery = Battery()
    assert battery.led_brightness() == pytest.approx(1.0, abs=0.02)
    assert battery.open_circuit_v() == pytest.approx(3.16)
    assert battery.supply_v(True) < battery.supply_v(False)
    # LED current with fresh cells: (3.16 - sag - 1.35 V) / 33 ohm ~ 54 mA.
    assert battery.current_ma(True) == pytest.approx(1.0 + 54.0, abs=2.0)
    assert cell_voltage(0.5) == pytest.approx(1.27)
    # Idle only: 1 mA for 10 h draws 10 mAh.
    battery.advance(36000.0, led_on=False)
    assert battery.drawn_mah == pytest.approx(10.0)


def test_battery_rejects_bad_charge() -> None:
    with pytest.raises(ValueError, match="charge"):
        Battery(BatteryConfig(), charge=1.5)


def _world() -> World:
    lms = {
        i: SimLandmark(i, np.array([i, 0, 2.5]), np.array([i, 0, 2.5]), f"0013A2004100000{i}",
                       Battery(), radio_dead=(i == 3))
        for i in (1, 2, 3)
    }  # fmt: skip
    return World(lms)


def test_radio_switches_leds_reads_battery_and_dead_landmark_times_out() -> None:
    world = _world()
    radio = SimRadio(world, rng=np.random.default_rng(0), latency_s=(0.001, 0.002), loss=0.0,
                     timeout_s=0.01, discover_s=0.001)  # fmt: skip

    async def run() -> tuple[object, ...]:
        off = await radio.set_pin("0013A20041000002", False)
        lit_after = world.lit_ids()
        mv = await radio.read_supply_mv("0013a20041000001")
        dead = await radio.set_pin("0013A20041000003", False)
        dead_mv = await radio.read_supply_mv("0013A20041000003")
        unknown = await radio.set_pin("FFFFFFFFFFFFFFFF", True)
        found = await radio.discover()
        return off, lit_after, mv, dead, dead_mv, unknown, found

    off, lit_after, mv, dead, dead_mv, unknown, found = asyncio.run(run())
    assert off is True and lit_after == {1, 3}
    assert mv == round(world.landmarks[1].battery.supply_v(True) * 1000)
    assert dead is False and dead_mv is None and unknown is False
    assert world.landmarks[3].led_on  # never reached
    assert found == [("0013A20041000001", "LM1"), ("0013A20041000002", "LM2")]


def test_radio_loses_packets_at_the_configured_rate() -> None:
    world = _world()
    radio = SimRadio(world, rng=np.random.default_rng(5), latency_s=(0.0, 0.0), loss=0.3,
                     timeout_s=0.0)  # fmt: skip

    async def run() -> list[bool]:
        return [await radio.set_pin("0013A20041000001", True) for _ in range(400)]

    acks = np.array(asyncio.run(run()))
    # Acknowledged when neither way is lost: 0.7 ** 2 = 0.49.
    assert acks.mean() == pytest.approx(0.49, abs=0.06)
