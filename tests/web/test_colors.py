from __future__ import annotations

from web.colors import (
    DOUBTED_COLOR,
    MODE_COLORS,
    UNKNOWN_COLOR,
    UNREACHABLE_COLOR,
    battery_color,
    landmark_color,
    mode_color,
)


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
    assert landmark_color(90.0, doubted=True) == DOUBTED_COLOR
    assert landmark_color(90.0, reachable=False, doubted=True) == UNREACHABLE_COLOR
    assert landmark_color(100.0) == (40, 200, 40)
    assert landmark_color(None) == UNKNOWN_COLOR
