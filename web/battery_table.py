"""The landmark battery table of the monitoring panel: every landmark, low first (or sorted
as staff choose), with its measured voltage, the days its cells have left at the current
LED schedule (the energy model), whether it is lit and why, and a flag before it dims."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

from web.services import LandmarkState

SortKey = Literal["low first", "days left", "volts", "duty", "id"]
SORT_KEYS: tuple[SortKey, ...] = ("low first", "days left", "volts", "duty", "id")


def _days(lm: LandmarkState) -> float:
    return lm.model_days if lm.model_days is not None else math.inf


def _volts(lm: LandmarkState) -> float:
    return lm.supply_mv if lm.supply_mv is not None else math.inf


def sort_landmarks(landmarks: Sequence[LandmarkState], key: SortKey) -> list[LandmarkState]:
    """The landmarks in the table's order (ties by ID); unknown readings last."""
    if key == "low first":
        return sorted(landmarks, key=lambda lm: (not lm.low, _days(lm), _volts(lm), lm.id))
    if key == "days left":
        return sorted(landmarks, key=lambda lm: (_days(lm), lm.id))
    if key == "volts":
        return sorted(landmarks, key=lambda lm: (_volts(lm), lm.id))
    if key == "duty":
        return sorted(landmarks, key=lambda lm: (-(lm.duty or 0.0), lm.id))
    if key == "id":
        return sorted(landmarks, key=lambda lm: lm.id)
    raise ValueError(f"battery table: sort by one of {SORT_KEYS}, got {key!r}")


def battery_table(landmarks: Sequence[LandmarkState], key: SortKey = "low first") -> str:
    """Markdown table: id, volts, days left ("days": the model at the current schedule; the
    voltage trend's in brackets), duty, lit and why, and LOW when it dims within a week."""
    rows = [
        "| id | volts | days | duty | lit | why |",
        "|---|---|---|---|---|---|",
    ]
    for lm in sort_landmarks(landmarks, key):
        volts = "-" if lm.supply_mv is None else f"{lm.supply_mv / 1000:.2f}"
        days = "-" if lm.model_days is None else f"{lm.model_days:.0f}"
        if lm.days_left is not None:
            days += f" ({lm.days_left:.0f})"
        duty = "-" if lm.duty is None else f"{100 * lm.duty:.0f}%"  # no space: no wrap
        flags = (" **LOW**" if lm.low else "") + ("" if lm.reachable else " (unreachable)")
        why = lm.lit_reason or ("" if lm.lit else "dark")
        rows.append(
            f"| {lm.id}{flags} | {volts} | {days} | {duty} | {'on' if lm.lit else 'off'} | {why} |"
        )
    return "\n".join(rows)
