"""When the sleeping landmarks stay awake (server/led_schedule/wake_window.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import pytest

from server.led_schedule.site import gateway_config, wake_window
from server.led_schedule.wake_window import WakeWindow, WakeWindowConfig
from server.settings import Settings


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
    environment too."""

    def policy(**kw: Any) -> str:
        return Settings(data_dir=Path("/nonexistent"), **kw).led_policy

    assert policy() == "all_lit"
    assert policy(radio_sleep_period_s=0.5) == "scheduled"
    assert policy(led_policy="auto", radio_sleep_period_s=2.0) == "scheduled"
    assert policy(led_policy="all_lit", radio_sleep_period_s=0.5) == "all_lit"
    assert policy(led_policy="scheduled") == "scheduled"
    monkeypatch.setenv("IRLOC_RADIO_SLEEP_PERIOD_S", "0.5")
    assert policy() == "scheduled"
    monkeypatch.setenv("IRLOC_LED_POLICY", "all_lit")
    assert policy() == "all_lit"
    with pytest.raises(ValueError, match="led_policy"):
        policy(led_policy="sometimes")
