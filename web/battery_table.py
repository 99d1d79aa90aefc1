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


COLUMNS = ("id", "volts", "days", "duty", "lit", "why")
COLUMN_WIDTHS = ("27%", "12%", "17%", "10%", "8%", "26%")
"""Fixed column widths of the HTML table: the columns no longer jump between refreshes."""
DAYS_NOTE = (
    "days: how long the cells last at this landmark's LED duty so far (the energy model, from "
    "the measured voltage; the voltage trend's estimate in brackets). Just after a start every "
    "LED is lit while the robots identify, so the duty is high and the days read low: they "
    "settle within the first hour, and LOW is only flagged after it."
)


def battery_rows(
    landmarks: Sequence[LandmarkState], key: SortKey = "low first"
) -> list[tuple[str, ...]]:
    """The table's cells (`COLUMNS`), one tuple a landmark, in the chosen order."""
    rows: list[tuple[str, ...]] = []
    for lm in sort_landmarks(landmarks, key):
        volts = "-" if lm.supply_mv is None else f"{lm.supply_mv / 1000:.2f}"
        days = "-" if lm.model_days is None else f"{lm.model_days:.0f}"
        if lm.days_left is not None:
            days += f" ({lm.days_left:.0f})"
        duty = "-" if lm.duty is None else f"{100 * lm.duty:.0f}%"  # no space: no wrap
        flags = (" **LOW**" if lm.low else "") + ("" if lm.reachable else " (unreachable)")
        why = lm.lit_reason or ("" if lm.lit else "dark")
        rows.append((f"{lm.id}{flags}", volts, days, duty, "on" if lm.lit else "off", why))
    return rows


def battery_table(landmarks: Sequence[LandmarkState], key: SortKey = "low first") -> str:
    """Markdown table: id, volts, days left ("days": the model at the current schedule; the
    voltage trend's in brackets), duty, lit and why, and LOW when it dims within a week."""
    rows = [
        "| " + " | ".join(COLUMNS) + " |",
        "|---|---|---|---|---|---|",
    ]
    rows += ["| " + " | ".join(cells) + " |" for cells in battery_rows(landmarks, key)]
    return "\n".join(rows)


def battery_html(
    landmarks: Sequence[LandmarkState], key: SortKey = "low first", *, max_rows: int = 10
) -> str:
    """The panel's table as HTML with fixed column widths, the first `max_rows` landmarks
    in the chosen order and a line naming how many more there are (39 rows pushed the
    events off the screen), then what "days" means."""
    rows = battery_rows(landmarks, key)
    cols = "".join(f'<col style="width:{w}">' for w in COLUMN_WIDTHS)
    head = "".join(f'<th style="text-align:left">{c}</th>' for c in COLUMNS)
    body = "".join(
        "<tr>" + "".join(f"<td>{_cell(c)}</td>" for c in cells) + "</tr>"
        for cells in rows[:max_rows]
    )
    more = len(rows) - max_rows
    tail = (
        f'<div style="opacity:0.75">... and {more} more (change the order above, or '
        "<code>GET /api/v1/leds/status</code>)</div>"
        if more > 0
        else ""
    )
    return (
        '<div style="font-size:0.82em"><table style="table-layout:fixed;width:100%;'
        f'border-collapse:collapse;white-space:nowrap;overflow:hidden">{cols}<tr>{head}</tr>'
        f'{body}</table>{tail}<div style="opacity:0.75;margin-top:4px;white-space:normal">'
        f"{DAYS_NOTE}</div></div>"
    )


def _cell(text: str) -> str:
    """A cell's markdown as HTML (only bold is used) with `<`, `>`, `&` escaped."""
    import html

    out = html.escape(text)
    while "**" in out:
        out = out.replace("**", "<b>", 1).replace("**", "</b>", 1)
    return f'<span style="overflow:hidden;text-overflow:ellipsis;display:block">{out}</span>'
