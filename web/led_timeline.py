"""`LedTimeline`: the site's LED states over the last seconds, to know them at a frame's time.

The gateway publishes every LED state (`localizer.events.LedsChanged`: confirmed lit set from
`t_ns` on, and the LEDs whose radio command is in flight, `changing`). Pose updates reach the
viewer later than their frames, and robots identify by darkening one LED for a moment, so the
LEDs *now* are not the LEDs a frame saw: `at` answers for the frame's own time, with the
LEDs that were switched shortly before it (the localizer may not have taken them up again yet)
or were being switched, whose state at the frame is not to be relied on.

Pure: events in, sets out; not thread-safe (the caller locks).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from localizer.events import LedsChanged


@dataclass(frozen=True)
class LedsAt:
    """The LEDs at one time.

    Attributes:
        lit: landmarks whose LED was (confirmed) lit.
        unsure: landmarks whose LED was being switched, or was switched within the quiet time
            before (their use in that frame says nothing about them).
    """

    lit: frozenset[int]
    unsure: frozenset[int]


@dataclass(frozen=True)
class _State:
    t_ns: int
    lit: frozenset[int]
    changing: frozenset[int]


class LedTimeline:
    """The LED states published over the last `keep_s` seconds.

    Args:
        keep_s: states older than this (behind the newest) are dropped, except the one still
            in force then, seconds.
    """

    def __init__(self, *, keep_s: float = 60.0) -> None:
        if not keep_s > 0:
            raise ValueError(f"keep_s must be > 0, got {keep_s}")
        self.keep_s = keep_s
        self._states: deque[_State] = deque()

    def add(self, event: LedsChanged, landmarks: Iterable[int]) -> None:
        """One published state; `landmarks`: every landmark the radio controls (what
        `all_lit` means). A state older than the newest is stale and ignored (the gateway
        stamps its states in order; a snapshot read while a newer one arrived is not)."""
        t_ns = event.t_ns
        if self._states and t_ns < self._states[-1].t_ns:
            return
        self._states.append(_State(t_ns, event.lit_among(landmarks), frozenset(event.changing)))
        horizon = t_ns - round(self.keep_s * 1e9)
        while len(self._states) >= 2 and self._states[1].t_ns <= horizon:
            self._states.popleft()

    def at(self, t_ns: int, *, quiet_s: float) -> LedsAt | None:
        """The LEDs at `t_ns`; None when no state known covers that time (before the first
        one kept)."""
        states = self._states
        if not states or t_ns < states[0].t_ns:
            return None
        k = len(states) - 1
        while states[k].t_ns > t_ns:
            k -= 1
        now = states[k]
        unsure = set(now.changing)
        since = t_ns - round(quiet_s * 1e9)
        j = k
        while j >= 1 and states[j].t_ns > since:  # switches within the quiet time
            unsure |= states[j].changing | (states[j].lit ^ states[j - 1].lit)
            j -= 1
        return LedsAt(now.lit, frozenset(unsure))
