"""Colours of the viewer: battery level, localizer mode, landmark state.

Colours are RGB tuples of ints in 0-255 (what viser takes).
"""

from __future__ import annotations

import math

from localizer.events import Mode

RGB = tuple[int, int, int]

MODE_COLORS: dict[str, RGB] = {
    "landmark": (40, 160, 60),  # green: localized from landmarks
    "dead_reckoning": (230, 160, 20),  # amber: odometry only
    "identifying": (60, 120, 220),  # blue: finding out which landmark is which
    "lost": (210, 40, 40),  # red
}
UNKNOWN_COLOR: RGB = (150, 150, 150)
UNREACHABLE_COLOR: RGB = (120, 40, 160)
DOUBTED_COLOR: RGB = (235, 80, 200)  # pink: robots expected it but did not use it
LIT_COLOR: RGB = (255, 255, 200)
DARK_COLOR: RGB = (50, 50, 60)


def battery_color(percent: float | None) -> RGB:
    """Red (0 %) through yellow (50 %) to green (100 %); grey when unknown (None)."""
    if percent is None or not math.isfinite(percent):
        return UNKNOWN_COLOR
    p = min(100.0, max(0.0, percent)) / 100.0
    if p < 0.5:
        return (220, round(40 + 380 * p), 40)  # red -> yellow
    return (round(220 - 360 * (p - 0.5)), 200, 40)  # yellow -> green


def mode_color(mode: Mode | str | None) -> RGB:
    """The colour of a localizer mode; grey for None or an unknown mode."""
    if mode is None:
        return UNKNOWN_COLOR
    return MODE_COLORS.get(mode, UNKNOWN_COLOR)


def landmark_color(percent: float | None, *, reachable: bool = True, doubted: bool = False) -> RGB:
    """A landmark sphere's colour: unreachable, then doubted, take precedence over battery."""
    if not reachable:
        return UNREACHABLE_COLOR
    if doubted:
        return DOUBTED_COLOR
    return battery_color(percent)


SURVEY_STATE_COLORS: dict[str, RGB] = {  # the survey panel's estimates, by state
    "anchor": (40, 110, 230),  # blue: locked, held at its surveyed position
    "converging": (235, 160, 20),  # amber: placed, still uncertain
    "converged": (40, 170, 70),  # green: 1-sigma within the target
    "flagged": (215, 40, 40),  # red: something looks wrong (moved, swapped radios)
    "unseen": (150, 150, 150),  # grey: never identified yet (drawn at its map position)
}
SURVEY_STATE_NAMES: dict[str, str] = {
    "anchor": "anchor (locked, held)",
    "converging": "converging",
    "converged": "converged (1-sigma <= 5 mm)",
    "flagged": "flagged (moved? radios swapped?)",
    "unseen": "not identified yet (map position)",
}
ROUTE_COLOR: RGB = (190, 50, 200)  # the survey's suggested route, on the floor

ROBOT_COLORS: tuple[RGB, ...] = (  # trails, one per robot: hues far from the modes' and
    (110, 50, 190),  # violet     the footprint's (the scene's tone mapping lightens
    (190, 0, 110),  # magenta     every colour and shifts its hue by up to 20 degrees)
    (0, 150, 140),  # teal
    (120, 120, 0),  # olive
    (90, 90, 90),  # dark grey
)


def robot_color(index: int) -> RGB:
    """The colour of the `index`-th robot (in the order robots appear; it repeats after
    `len(ROBOT_COLORS)` robots)."""
    return ROBOT_COLORS[index % len(ROBOT_COLORS)]
