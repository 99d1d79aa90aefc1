"""Sleeping landmarks: the gateway's wake tracking (rf_gateway/wake.py), its sleep settings,
and the emulator's sleeping remotes."""

from __future__ import annotations

import pytest

from rf_gateway.config import SleepConfig
from rf_gateway.emulator import EmulatedRemote
from rf_gateway.wake import WakeTracker


def test_awake_radios_and_unknown_landmarks_are_sent_to_at_once() -> None:
    assert WakeTracker(None).send_delay_s(1, 5.0) == 0.0
    assert WakeTracker(SleepConfig(1.0)).send_delay_s(1, 5.0) == 0.0


def test_a_slow_answer_fixes_the_phase_and_the_next_command_waits_for_the_wake_up() -> None:
    sl = SleepConfig(1.0, wake_s=2.0, air_s=0.04, lead_s=0.06)
    w = WakeTracker(sl)
    w.answered(3, sent_s=10.0, answered_s=10.44)  # waited for a wake-up at ~10.42
    # Within ST of the answer it is awake: send now.
    assert w.send_delay_s(3, 11.0) == 0.0
    # Later it sleeps again: send `lead + air` before its next wake-up (phase 0.42).
    delay = w.send_delay_s(3, 13.0)
    assert 13.0 + delay == pytest.approx(13.42 - 0.10, abs=1e-9)
    # Right before a wake-up, the next one is too close: wait for the one after.
    assert 13.38 + w.send_delay_s(3, 13.38) == pytest.approx(14.32, abs=1e-9)
    w.forget(3)
    assert w.send_delay_s(3, 13.0) == 0.0


def test_a_quick_answer_keeps_the_phase_and_extends_the_wake() -> None:
    w = WakeTracker(SleepConfig(1.0, wake_s=2.0))
    w.answered(3, 10.0, 10.44)
    w.answered(3, 11.5, 11.56)  # awake: a poll interval, no new phase
    assert w.send_delay_s(3, 13.0) == 0.0  # awake until 13.56
    assert 14.0 + w.send_delay_s(3, 14.0) == pytest.approx(14.415 - 0.13, abs=1e-9)


def test_sleep_settings_are_checked_and_give_the_transport_timeout() -> None:
    assert SleepConfig(1.0).command_timeout_s == pytest.approx(2.0)
    with pytest.raises(ValueError, match="SP"):
        SleepConfig(0.1)
    with pytest.raises(ValueError, match="wake_s"):
        SleepConfig(1.0, wake_s=-1.0)


def test_an_emulated_sleeping_remote_answers_at_its_wake_up() -> None:
    remote = EmulatedRemote("0013A20041000001", sleep_period_s=2.0, sleep_phase_s=0.5)
    assert remote.wake_delay_s(100.0) == pytest.approx(0.5)
    assert remote.wake_delay_s(100.75) == pytest.approx(1.75)
    assert EmulatedRemote("0013A20041000002").wake_delay_s(100.0) == 0.0
