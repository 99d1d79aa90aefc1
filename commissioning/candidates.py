"""What the identification wizard offers: doubted landmarks and new radios from discovery.

Pure functions over the map's IDs, the doubt records (`commissioning.doubt`) and the
discovery result (the same `POST /radio/discover` runs: radios that answer and are not in the map).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

from commissioning.doubt import Doubt
from commissioning.types import Candidate

MAX_LANDMARK_ID = 2**31 - 1
"""The largest landmark ID (`store.models.MAX_LANDMARK_ID` checks it is the same)."""

_TRAILING_DIGITS = re.compile(r"(\d+)\s*$")


def landmark_id_for_radio(node_id: str, taken: set[int]) -> int:
    """The ID a new radio gets: the number its node identifier ends with ("LM105" -> 105)
    when that ID is free, else one above the largest taken ID. Adds it to `taken`."""
    m = _TRAILING_DIGITS.search(node_id)
    lid = int(m.group(1)) if m else -1
    if not 0 <= lid <= MAX_LANDMARK_ID or lid in taken:
        lid = max(taken, default=0) + 1
    taken.add(lid)
    return lid


def new_radio_candidates(
    radios: Iterable[tuple[str, str]], taken_ids: Iterable[int]
) -> list[Candidate]:
    """Candidates for radios (address, node identifier) that are not in the map, each with
    the landmark ID it will get (`landmark_id_for_radio`), in address order."""
    taken = set(taken_ids)
    out = []
    for address, node_id in sorted(radios):
        lid = landmark_id_for_radio(node_id, taken)
        label = f" ({node_id})" if node_id else ""
        out.append(Candidate(lid, address, f"new radio {address}{label}"))
    return out


def doubted_candidates(doubted: Mapping[int, Doubt], locked: set[int]) -> list[Candidate]:
    """Candidates for doubted landmarks that are not locked (surveyed), by ID."""
    return [
        Candidate(lid, None, f"doubted: {d.reason}")
        for lid, d in sorted(doubted.items())
        if lid not in locked
    ]
