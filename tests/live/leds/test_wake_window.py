"""When the sleeping landmarks stay awake (lighting/wake_window.py)."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest

from lighting.wake_window import WakeWindow, WakeWindowConfig
from live.leds.runtime import LedScheduler
from live.leds.wiring import gateway_config, wake_window
from live.settings import SIM_SLEEP_PERIOD_S, Settings


def test_the_window_opens_while_a_robot_identifies_and_closes_after_it_held_a_pose() -> None:
    w = WakeWindow(WakeWindowConfig(normal_wake_s=1.0, identify_wake_s=30.0, relax_after_s=5.0))
    assert w.update(0.0, identifying=False) is None  # nothing to change at a calm start
    assert w.update(1.0, identifying=True) == 30.0
    assert w.update(1.25, identifying=True) is None  # sent once, not every plan
    assert w.update(3.0, identifying=False) is None  # posed since 3 s
    assert w.update(6.0, identifying=True) is None  # lost again: still open, timer reset
    assert w.update(7.0, identifying=False) is None
    assert w.update(11.9, identifying=False) is None
    assert w.update(12.0, identifying=False) == 1.0  # 5 s with every robot posed
    assert not w.open
    assert w.update(20.0, identifying=False) is None


def test_a_window_shorter_than_the_normal_time_awake_is_refused() -> None:
    with pytest.raises(ValueError, match="normal_wake_s"):
        WakeWindowConfig(normal_wake_s=2.0, identify_wake_s=1.0)


def test_a_window_the_gateway_opened_at_start_costs_no_st_commands() -> None:
    """Sleeping radios under the schedule: the gateway's start-up broadcast sets `ST` to the
    window's own 30 s, so the window starts open and only its closing is sent; `all_lit`
    (no window to close it) and awake radios broadcast no window."""

    def settings(policy: Literal["scheduled", "all_lit"], sleep: float | None) -> Settings:
        return Settings(data_dir=Path("/nonexistent"), led_policy=policy,
                        radio_sleep_period_s=sleep)  # fmt: skip

    sched = settings("scheduled", 0.5)
    assert gateway_config(sched).start_awake_s == WakeWindowConfig().identify_wake_s
    assert gateway_config(settings("all_lit", 0.5)).start_awake_s is None
    assert gateway_config(settings("scheduled", None)).start_awake_s is None
    w = wake_window(sched, opened_s=gateway_config(sched).start_awake_s)
    assert w is not None and w.open
    assert w.update(0.0, identifying=True) is None  # already open: nothing sent
    assert w.update(1.0, identifying=False) is None
    assert w.update(6.0, identifying=False) == 1.0  # closing is sent
    closed = wake_window(sched, opened_s=None)
    assert closed is not None and not closed.open


def test_the_default_led_policy_follows_the_radios_sleep(monkeypatch: pytest.MonkeyPatch) -> None:
    """`auto`, the default: the schedule with sleeping radios (where it meets the battery
    and accuracy targets), every LED lit with awake ones; a policy given is kept, from the
    environment too. The simulated site's radios sleep unless told otherwise (0: awake), an
    XBee radio's are awake unless told."""

    def settings(**kw: Any) -> Settings:
        return Settings(data_dir=Path("/nonexistent"), **kw)

    def policy(**kw: Any) -> str:
        return settings(**kw).led_policy

    assert settings().radio_sleep_period_s == SIM_SLEEP_PERIOD_S
    assert policy() == "scheduled"
    assert policy(radio_sleep_period_s=0) == policy(radio_sleep_period_s=None) == "all_lit"
    assert settings(radio_sleep_period_s=0).radio_sleep_period_s is None
    assert settings(radio="xbee:/dev/ttyUSB0").radio_sleep_period_s is None
    assert policy(radio="xbee:/dev/ttyUSB0") == "all_lit"
    assert policy(radio="xbee:/dev/ttyUSB0", radio_sleep_period_s=0.5) == "scheduled"
    assert policy(led_policy="auto", radio_sleep_period_s=2.0) == "scheduled"
    assert policy(led_policy="all_lit", radio_sleep_period_s=0.5) == "all_lit"
    assert policy(led_policy="scheduled", radio_sleep_period_s=None) == "scheduled"
    monkeypatch.setenv("IRLOC_RADIO_SLEEP_PERIOD_S", "0")
    assert policy() == "all_lit"
    monkeypatch.setenv("IRLOC_RADIO_SLEEP_PERIOD_S", "0.5")
    assert policy(radio="xbee:/dev/ttyUSB0") == "scheduled"
    monkeypatch.setenv("IRLOC_LED_POLICY", "all_lit")
    assert policy() == "all_lit"
    with pytest.raises(ValueError, match="led_policy"):
        policy(led_policy="sometimes")
    with pytest.raises(ValueError, match=r"radio_sleep_period_s.*0\.32"):
        policy(radio_sleep_period_s=0.1)


def test_a_pin_of_someone_switching_leds_opens_the_window_until_it_ends() -> None:
    """The survey's blinks and the wizard switch one LED at a time and wait for each: their
    pins (`awake=True`) open the window as a robot's identification does, a staff member's
    pin does not, and releasing them lets it close."""
    sent: list[float] = []

    async def set_awake(wake_s: float) -> None:
        sent.append(wake_s)

    async def body() -> None:
        now = [0]
        window = WakeWindow(WakeWindowConfig(normal_wake_s=1.0, identify_wake_s=30.0))
        sched = LedScheduler(
            lambda: ([7, 8], np.zeros((2, 3))), lambda: [], lambda name: 1.0, lambda: None,
            lambda: now[0], set_awake=set_awake, wake_window=window,
        )  # fmt: skip

        async def step(t_s: float) -> None:
            now[0] = round(t_s * 1e9)
            sched.step(now[0])
            await asyncio.sleep(0)  # the `ST` task runs

        sched.pin([7], "ladder check", 60.0)
        await step(0.0)
        assert sent == [] and not window.open
        sched.pin([7, 8], "survey", 60.0, awake=True)
        await step(1.0)
        assert sent == [30.0]
        await step(10.0)
        assert sent == [30.0]  # sent once
        assert sched.unpin_reason("survey") == 2
        await step(11.0)
        await step(16.5)
        assert sent == [30.0, 1.0]  # closed 5 s after the last switching pin ended
        assert [p[1] for p in sched.pins()] == ["ladder check"]

    asyncio.run(body())
