from __future__ import annotations

import pytest

from web.colors import (
    MODE_COLORS,
    NEVER_SEEN_COLOR,
    UNKNOWN_COLOR,
    UNREACHABLE_COLOR,
    BatteryScale,
    battery_color,
    battery_percent,
    landmark_color,
    mode_color,
)


def test_battery_percent_is_linear_between_cutoff_and_full_and_clipped() -> None:
    assert battery_percent(2100) == 0.0
    assert battery_percent(3200) == 100.0
    assert battery_percent(2650) == pytest.approx(50.0)
    assert battery_percent(1800) == 0.0
    assert battery_percent(3500) == 100.0
    assert battery_percent(2500, BatteryScale(full_mv=3000, cutoff_mv=2000)) == pytest.approx(50.0)


def test_battery_percent_refuses_nan_and_bad_scale() -> None:
    with pytest.raises(ValueError, match="finite"):
        battery_percent(float("nan"))
    with pytest.raises(ValueError, match="full_mv"):
        BatteryScale(full_mv=2000, cutoff_mv=2100)


def test_battery_color_runs_red_yellow_green() -> None:
    assert battery_color(0.0) == (220, 40, 40)
    assert battery_color(50.0) == (220, 200, 40)
    assert battery_color(100.0) == (40, 200, 40)
    assert battery_color(None) == UNKNOWN_COLOR
    r_low, g_low, _ = battery_color(20.0)
    r_high, g_high, _ = battery_color(80.0)
    assert r_low > r_high and g_low < g_high


def test_mode_and_landmark_colors() -> None:
    assert mode_color("lost") == MODE_COLORS["lost"]
    assert mode_color("landmark") != mode_color("dead_reckoning")
    assert mode_color(None) == UNKNOWN_COLOR
    assert landmark_color(90.0, reachable=False) == UNREACHABLE_COLOR
    assert landmark_color(90.0, seen=False) == NEVER_SEEN_COLOR
    assert landmark_color(100.0) == (40, 200, 40)
