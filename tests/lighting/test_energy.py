"""The landmark energy model (lighting/energy.py) and the sleeping simulated radio."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from bench.virtual_site import run_virtual
from lighting.battery import Battery, BatteryConfig
from lighting.energy import (
    DutyCycle,
    EnergyLedger,
    RadioPower,
    RadioSleep,
    charge_from_voltage,
    combine_duty,
    predict_life_days,
    radio_average_ma,
)
from sim.radio import SimRadio
from sim.world import SimLandmark, World


def test_always_lit_with_an_awake_radio_lasts_under_two_days() -> None:
    # 2500 mAh, ~50 mA LED (falling with the voltage) + 17 mA receiver.
    days = predict_life_days(DutyCycle(1.0))
    assert 1.6 < days < 2.1
    # Dark, awake: the receiver alone, 2500 mAh * 93 % usable / 17 mA.
    assert predict_life_days(DutyCycle(0.0)) == pytest.approx(2500 * 0.93 / 17 / 24, rel=0.03)


def test_a_sleeping_radio_costs_a_fraction_of_a_milliamp() -> None:
    power = RadioPower()
    one_s = radio_average_ma(power, RadioSleep(1.0))
    # 12 ms awake per second (11 ms receiving at 17 mA, 1 ms sending at 40 mA) + 2 uA.
    assert one_s == pytest.approx((0.011 * 17 + 0.001 * 40) / 1.0 + 0.002 * 0.988, rel=1e-6)
    assert radio_average_ma(power, RadioSleep(0.5)) == pytest.approx(2 * one_s, rel=0.01)
    assert predict_life_days(DutyCycle(0.0), sleep=RadioSleep(1.0)) > 300


def test_life_scales_with_the_led_duty_and_the_day_combines_shift_and_idle() -> None:
    day = combine_duty([(8.0, DutyCycle(0.3, 0.06)), (16.0, DutyCycle(0.0, 0.0))])
    assert day.led_duty == pytest.approx(0.1)
    assert day.messages_per_s == pytest.approx(0.02)
    sleep = RadioSleep(0.5)
    ten = predict_life_days(DutyCycle(0.1), sleep=sleep)
    twenty = predict_life_days(DutyCycle(0.05), sleep=sleep)
    assert 1.6 < twenty / ten < 2.0  # the radio's share keeps it under 2x
    # Messages: each keeps the radio awake ST polling every 100 ms.
    busy = predict_life_days(DutyCycle(0.1, 1.0), sleep=sleep)
    assert busy < ten


def test_the_ledger_charges_what_the_landmark_did() -> None:
    ledger = EnergyLedger(sleep=RadioSleep(1.0))
    radio = ledger.advance(7, 3600.0, led_ma=50.0)
    e = ledger.landmarks[7]
    assert e.led_mah == pytest.approx(50.0)
    assert e.led_duty == 1.0
    assert radio == pytest.approx(ledger.radio_ma())
    q = ledger.message(7, extra_awake_s=10.0)
    assert e.messages == 1
    assert q == pytest.approx(
        RadioPower().charge_per_message_mah() + 10.0 * RadioSleep(1.0).awake_ma(RadioPower()) / 3600
    )


def test_charge_from_voltage_inverts_the_discharge_curve() -> None:
    b = Battery(BatteryConfig(), charge=0.4)
    mv = b.open_circuit_v() * 1000
    assert charge_from_voltage(mv) == pytest.approx(0.4, abs=1e-6)


def _world() -> World:
    lm = SimLandmark(5, np.zeros(3), np.zeros(3), "0013A20041000005", Battery())
    return World({5: lm})


def test_a_sleeping_radio_delivers_at_the_next_wake_up_then_within_a_poll() -> None:
    world = _world()
    radio = SimRadio(world, rng=np.random.default_rng(0), latency_s=(0.01, 0.01), loss=0.0,
                     sleep=RadioSleep(1.0, wake_s=0.3))  # fmt: skip
    assert world.energy is not None and world.energy.sleep == RadioSleep(1.0, wake_s=0.3)

    async def main() -> list[tuple[float, float]]:
        loop = asyncio.get_running_loop()
        took = []
        for level in (False, True, False):
            t = loop.time()
            assert await radio.set_pin("0013A20041000005", level)
            took.append((t, loop.time() - t))
        await asyncio.sleep(0.5)  # asleep again
        t = loop.time()
        assert await radio.set_pin("0013A20041000005", True)
        took.append((t, loop.time() - t))
        return took

    # virtual time (no waiting): a busy machine's late wake-ups cannot shift the timings
    (t1, first), (_, second), (_, third), (t4, after) = run_virtual(main())
    phase = radio.wake_delay_s(5, 0.0)  # the landmark's wake-up phase in its 1 s cycle
    assert first == pytest.approx((phase - t1 - 0.0025) % 1.0 + 0.01, abs=0.05)
    assert second <= 0.15 and third <= 0.15  # awake: within a poll (100 ms)
    assert after == pytest.approx((phase - t4 - 0.0025) % 1.0 + 0.01, abs=0.05)
    assert world.energy.landmarks[5].messages == 4


def test_a_long_time_awake_keeps_commands_within_a_poll_and_is_charged() -> None:
    """`set_awake_time` (XBee `ST`) raised to 5 s: commands 3 s later still arrive within a
    poll interval; the ledger charges the 5 s awake at the polling current; setting it back
    to 0.3 s lets the radio sleep again 0.3 s after that command."""
    world = _world()
    radio = SimRadio(world, rng=np.random.default_rng(0), latency_s=(0.01, 0.01), loss=0.0,
                     sleep=RadioSleep(1.0, wake_s=0.3))  # fmt: skip

    async def main() -> tuple[float, float, float]:
        loop = asyncio.get_running_loop()
        assert await radio.set_awake_time("0013A20041000005", 5.0)
        await asyncio.sleep(3.0)
        t = loop.time()
        assert await radio.set_pin("0013A20041000005", True)
        awake_took = loop.time() - t
        assert await radio.set_awake_time("0013A20041000005", 0.3)
        await asyncio.sleep(0.6)
        t = loop.time()
        assert await radio.set_pin("0013A20041000005", False)
        return awake_took, loop.time() - t, t

    awake_took, asleep_took, t = run_virtual(main())  # virtual time: no waiting
    assert awake_took <= 0.12
    phase = radio.wake_delay_s(5, 0.0)
    assert asleep_took == pytest.approx((phase - t - 0.0025) % 1.0 + 0.01, abs=0.05)
    assert world.energy is not None
    e = world.energy.landmarks[5]
    polling_ma = RadioSleep(1.0).awake_ma(RadioPower())
    # awake from the first command until 0.3 s after the third (3.3 s), and 0.3 s after
    # the last: the 5 s of the first `ST` that the third cut short are not charged
    assert e.message_mah == pytest.approx(
        4 * RadioPower().charge_per_message_mah() + 3.6 * polling_ma / 3600, rel=0.05
    )
    with pytest.raises(ValueError, match="ST"):
        run_virtual(radio.set_awake_time("0013A20041000005", 100.0))


def test_the_ledger_splits_the_radio_charge_into_sleep_wake_ups_and_commands() -> None:
    ledger = EnergyLedger(sleep=RadioSleep(0.5))
    ledger.advance(7, 3600.0, led_ma=0.0)
    ledger.message(7, extra_awake_s=1.0)
    e = ledger.landmarks[7]
    assert e.idle_mah + e.wake_mah + e.message_mah == pytest.approx(e.radio_mah)
    assert e.idle_mah == pytest.approx(0.002 * (1 - 0.012 / 0.5), rel=1e-6)
    assert e.wake_mah == pytest.approx(ledger.radio_ma() - e.idle_mah, rel=1e-6)
    assert e.radio_ma == pytest.approx(e.radio_mah, rel=1e-9)  # over one hour
    # each 0.5 s wake-up sends one poll (1 ms), the command's answer 3 ms, 10 polls awake
    assert e.tx_s == pytest.approx(7200 * 0.001 + 0.003 + 10 * 0.001)
    # a measured radio current replaces the model in the life prediction
    modelled = predict_life_days(DutyCycle(0.0, 1 / 3600), sleep=RadioSleep(0.5))
    measured = predict_life_days(DutyCycle(0.0, 1 / 3600, e.radio_ma), sleep=RadioSleep(0.5))
    assert measured == pytest.approx(modelled, rel=0.02)
