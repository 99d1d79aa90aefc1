"""An LED state as one map sees it: restricted to that map's landmarks (a floor's, or the map
a recording holds)."""

from __future__ import annotations

from localizer.events import LedsChanged


def only_landmarks(event: LedsChanged, ids: frozenset[int]) -> LedsChanged:
    """An LED state restricted to the landmarks `ids` (one floor's map)."""
    if event.all_lit:
        return LedsChanged(event.t_ns, frozenset(), True, event.changing & ids)
    return LedsChanged(event.t_ns, event.lit & ids, False, event.changing & ids)
