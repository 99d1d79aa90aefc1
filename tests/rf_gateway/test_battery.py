from __future__ import annotations

import numpy as np
import pytest

from rf_gateway.battery import NS_PER_DAY, BatteryHistory, BatteryMonitorConfig, days_left


def test_days_left_extrapolates_a_linear_discharge_to_the_cutoff() -> None:
    rng = np.random.default_rng(0)
    t_days = np.linspace(0.0, 20.0, 41)
    mv = 3000.0 - 15.0 * t_days + rng.normal(0.0, 2.0, t_days.shape)
    got = days_left(t_days * NS_PER_DAY, mv, 2100.0)
    # true: (3000 - 15*20 - 2100) / 15 = 40 days after the last reading
    assert got is not None
    np.testing.assert_allclose(got, 40.0, rtol=0.02)


def test_days_left_is_none_when_flat_short_or_rising() -> None:
    t = np.array([0.0, 1.0, 2.0]) * NS_PER_DAY
    assert days_left(t, np.array([3000.0, 3000.0, 3000.0]), 2100.0) is None
    assert days_left(t, np.array([2900.0, 3000.0, 3100.0]), 2100.0) is None
    assert days_left(t[:2], np.array([3000.0, 2990.0]), 2100.0) is None
    assert days_left(t / 100.0, np.array([3000.0, 2990.0, 2980.0]), 2100.0) is None


def test_days_left_is_zero_below_cutoff_and_checks_shapes() -> None:
    t = np.array([0.0, 1.0, 2.0]) * NS_PER_DAY
    assert days_left(t, np.array([2200.0, 2100.0, 2000.0]), 2100.0) == 0.0
    with pytest.raises(ValueError, match="3 times but 2"):
        days_left(t, np.array([1.0, 2.0]), 2100.0)


def test_history_is_bounded_and_windowed() -> None:
    history = BatteryHistory(BatteryMonitorConfig(history_len=5, fit_window_days=3.0))
    for day in range(10):
        mv = 3000 - 100 * day if day < 7 else 2400 - 10 * (day - 6)
        reading = history.add(4, day * NS_PER_DAY, mv)
    assert len(history.readings(4)) == 5
    # the last 4 days (6..9): 2400, 2390, 2380, 2370 -> 10 mV/day -> 27 days to 2100 mV
    assert reading.days_left is not None
    np.testing.assert_allclose(reading.days_left, 27.0, rtol=1e-6)
    assert history.latest(4) == reading
    assert history.latest(5) is None
    history.forget(4)
    assert history.readings(4) == []
