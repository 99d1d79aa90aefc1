"""What the localizer knows of the LEDs: which are lit, which are being switched, since when,
and what it asked for.

The owner (server, replay, simulator) reports the LED state with `LedsChanged`; the localizer
asks for states with `LedRequest`s while it identifies landmarks by switching them. Between
the two, this object holds the localizer's knowledge of the ceiling's LEDs:

- the state last reported: the lit IDs (None: all lit, or nothing reported yet) and those
  whose switch is in flight (`changing`: their state unknown until a later report);
- since when: the time of the last change and the frames stamped since, so that a frame
  exposed while the LEDs were still settling is not taken as evidence of the new state;
- what it asked for: the last request not yet confirmed (a frame without a fix may be
  explained by it), whether all must be lit again (tracking resumed), and the
  identification sweep under way (its last request, so that none goes out twice).

Sans-I/O: plain state and methods, time arrives as an argument.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from localizer.events import LedRequest, LedsChanged
from localizer.identification import Identifier
from localizer.identification_config import IdentificationConfig
from localizer.landmark_map import LandmarkMap

_NS = 1e-9


class LedKnowledge:
    """The LED state as last reported, since when, and the requests made (module docstring).

    Attributes:
        lit: the IDs lit; None: all lit (or unknown: nothing reported yet).
        changing: the IDs whose switch is in flight (state unknown).
        t_changed_ns: when the reported state last changed; None: never.
        frames_since_change: frames stamped since then.
        t_requested_ns: when the last request not yet confirmed went out; None: none.
        want_all: all LEDs are to be lit again (tracking resumed after identifying).
        last_request: the sweep's last request (the same one is not sent twice).
        sweeping: an identification sweep is under way (its requests go out).
    """

    def __init__(self, landmark_map: LandmarkMap) -> None:
        self.lit: frozenset[int] | None = None
        self.changing: frozenset[int] = frozenset()
        self.t_changed_ns: int | None = None
        self.frames_since_change = 0
        self.t_requested_ns: int | None = None
        self.want_all = False
        self.last_request: LedRequest | None = None
        self.sweeping = False
        self.set_map(landmark_map)

    def set_map(self, landmark_map: LandmarkMap) -> None:
        """The landmarks "all lit" stands for (the map's)."""
        self._map = landmark_map
        self._all_ids = frozenset(int(i) for i in landmark_map.ids.tolist())
        self._lit_rows_memo: (
            tuple[frozenset[int] | None, frozenset[int], npt.NDArray[np.int64]] | None
        ) = None

    def reported(self, e: LedsChanged) -> None:
        """The owner reports the LED state in force from `e.t_ns` (confirms any request)."""
        lit = None if e.all_lit else frozenset(e.lit)
        if (lit, frozenset(e.changing)) != (self.lit, self.changing):
            self.t_changed_ns = e.t_ns
            self.frames_since_change = 0
        self.lit = lit
        self.changing = frozenset(e.changing)
        self.t_requested_ns = None

    def known_lit(self) -> frozenset[int] | None:
        """The IDs lit now (every mapped one when all are lit); None while a switch is in
        flight (the state is unknown)."""
        if self.changing:
            return None
        return self._all_ids if self.lit is None else self.lit

    def lit_for_evidence(self, t_ns: int, config: IdentificationConfig) -> frozenset[int] | None:
        """The LED state a frame stamped `t_ns` was surely exposed under (counts the frame);
        None (unknown) for the first `led_settle_frames` frames after a change and within
        its `led_settle_s`."""
        self.frames_since_change += 1
        if self.t_changed_ns is not None and (
            self.frames_since_change <= config.led_settle_frames
            or (t_ns - self.t_changed_ns) * _NS < config.led_settle_s
        ):
            return None
        return self.known_lit()

    def lit_rows(self) -> npt.NDArray[np.int64]:
        """Map rows of the landmarks surely lit (not being switched); remembered while the
        LED state and the map stay."""
        memo = self._lit_rows_memo
        if memo is not None and memo[0] is self.lit and memo[1] is self.changing:
            return memo[2]
        lit = (self._all_ids if self.lit is None else self.lit) - self.changing
        m = self._map
        rows = np.array([m.index_of(i) for i in sorted(lit) if i in m], np.int64)
        rows.setflags(write=False)
        self._lit_rows_memo = (self.lit, self.changing, rows)
        return rows

    def awaiting(self, t_ns: int, timeout_s: float) -> bool:
        """A request went out within `timeout_s` of `t_ns` and is not confirmed yet."""
        return self.t_requested_ns is not None and ((t_ns - self.t_requested_ns) * _NS <= timeout_s)

    def restart_sweep(self, sweep: bool) -> None:
        """Identification starts over: a sweep under way when `sweep`, nothing asked yet."""
        self.last_request = None
        self.sweeping = sweep

    def all_lit_request(self, t_ns: int) -> LedRequest | None:
        """The request to light all, once when `want_all` (None when all are lit already)."""
        if self.want_all:
            self.want_all = False
            if self.lit is not None:
                self.t_requested_ns = t_ns
                return LedRequest(all_lit=True)
        return None

    def sweep_request(self, t_ns: int, identifier: Identifier) -> list[LedRequest]:
        """The sweep's next request (`Identifier.next_request`), unless it is the last one
        again; the sweep ends with its request to light all once enough are identified."""
        req = identifier.next_request(t_ns)
        if req is None or req == self.last_request:
            return []
        self.last_request = req
        self.t_requested_ns = t_ns
        if req.all_lit and not req.dark and identifier.done:
            self.sweeping = False
        return [req]
