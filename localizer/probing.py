"""What to light next while identifying (live use of Sec. III-A): the probe plan.

One candidate landmark at a time is switched (`probe="darken_one"`: every LED lit but the
candidate; `"light_one"`: the paper's dark ceiling with the candidate alone lit), and the
identifier (`localizer/identification.py`) watches which spot changes. The plan:
- candidates in `order`: near a prior pose first; once a landmark has shown itself, those
  in view of where the robot can be when the command lands (the owner's `prefer`, from
  `candidate_order.py`), or without an owner's order those nearest to it;
- a candidate is finished when it shows new evidence, after `frames_per_led` frames with its
  probe in force, or when its switch is not confirmed within `led_timeout_s` (a dead
  battery, out of radio range);
- a landmark that showed itself on one side only (it came back when relit, but its
  darkening was not seen where evidence is taken, or the other way round) and is lit now is
  darkened again at once, up to `max_reprobes` times a round: it is in view now, and a
  second switch within `2 reference_max_age_s` confirms it;
- candidates another robot already darkened in front of this camera are skipped;
- every candidate tried: start over; enough identified: every LED lit.
It also measures the command latency (request to confirmed switch), which the owner uses
to predict where the robot is when the next probe lands.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from localizer.events import LedRequest
from localizer.identification_config import IdentificationConfig
from localizer.types import FloatArray

_NS = 1e-9


@dataclass(frozen=True)
class Progress:
    """What identification knows, for choosing the next probe.

    Attributes:
        identified: landmarks identified.
        shown: pieces of evidence seen so far per landmark (counts only grow).
        probed: ... of the kind a probe brings (darken_one: vanished; light_one: appeared;
            a landmark relit goes on appearing against the frames before for a while).
        unpaired: landmarks with recent evidence not yet confirmed, newest first.
        newest: the landmark that showed itself last (identified or not), if any.
        done: enough identified.
    """

    identified: Collection[int]
    shown: Mapping[int, int]
    probed: Mapping[int, int]
    unpaired: Sequence[int]
    newest: int | None
    done: bool


class ProbePlan:
    """The order of candidates and the probe in progress (sans-I/O).

    Args:
        config: tuning.
        landmark_ids: the map's landmark IDs (the default order).
        positions: their world positions, shape (N, 3), or None (to try a found landmark's
            neighbours next).
    """

    def __init__(
        self,
        config: IdentificationConfig,
        landmark_ids: Sequence[int],
        positions: FloatArray | None = None,
    ) -> None:
        self.config = config
        self._all_ids = [int(i) for i in landmark_ids]
        self.all_lit = frozenset(self._all_ids)
        xy = (
            np.zeros((len(self._all_ids), 2))
            if positions is None
            else np.asarray(positions, float).reshape(-1, 3)[:, :2]
        )
        self._xy = {lid: xy[k] for k, lid in enumerate(self._all_ids)}
        self.latency_s = config.command_latency_s
        self.restart(self._all_ids)

    def restart(self, order: Sequence[int]) -> None:
        """Try the candidates in `order` from the start."""
        self._order = deque(int(i) for i in order)
        self.current: int | None = None
        self._since_ns: int | None = None  # when the current probe was asked for
        self._frames = 0
        self._in_force = False
        self._flight_seen = False  # a switch was in flight since the request (latency)
        self._shown_at_start = 0
        self._dark_requested = False
        self._dark_seen = False
        self._all_requested = False
        self._neighbours_first = False
        self._lit_now: frozenset[int] = self.all_lit
        self._dark_frames: dict[int, int] = {}  # frames seen with only this one darkened
        self._tried: set[int] = set()  # candidates probed in this round
        self._reprobes: dict[int, int] = {}  # re-probes of one-sided landmarks, this round
        self._reprobed_at: dict[int, int] = {}  # their evidence count when re-probed

    # -- what happened -------------------------------------------------------------------------
    def _in_force_under(self, lit: frozenset[int]) -> bool:
        cur = self.current
        if cur is None:
            return False
        if self.config.probe == "light_one":
            return lit == frozenset({cur})
        return cur not in lit

    def note_frame(self, lit: frozenset[int]) -> None:
        """A frame taken under the known LED state `lit`."""
        self._lit_now = lit
        if self.config.probe == "light_one" and not lit:
            self._dark_seen = True
        if self._in_force_under(lit):
            self._frames += 1
        dark = self.all_lit - lit
        if len(dark) == 1:  # someone's darken probe: no need to ask for it again
            (lid,) = dark
            self._dark_frames[lid] = self._dark_frames.get(lid, 0) + 1

    def led_confirmed(self, t_ns: int, lit: frozenset[int] | None) -> None:
        """An LED state (None: unknown, a switch in flight): the candidate's frame count
        starts when its probe is in force; the time from its request to then is one sample
        of the command latency (when a switch was in flight in between)."""
        if lit is None:
            self._flight_seen = self._flight_seen or self._since_ns is not None
        in_force = lit is not None and self._in_force_under(lit)
        if in_force and not self._in_force:
            if self._since_ns is not None and self._flight_seen:
                sample = min(max((t_ns - self._since_ns) * _NS, 0.0), 5.0)
                a = self.config.latency_smoothing
                self.latency_s = (1 - a) * self.latency_s + a * sample
            self._flight_seen = False
            self._since_ns = t_ns
            self._frames = 0
        self._in_force = in_force

    # -- the order -----------------------------------------------------------------------------
    def prefer(self, order: Sequence[int], *, come_into_view: Collection[int] = ()) -> None:
        """Try the candidates in `order` next (the one being probed keeps its turn), then
        the rest as before. Candidates already tried in this round are not tried again,
        unless they are in `come_into_view` (out of view when last ordered)."""
        for i in come_into_view:
            self._dark_frames.pop(int(i), None)
            self._tried.discard(int(i))
        first = [int(i) for i in order if int(i) not in self._tried]
        chosen = set(first)
        rest = [i for i in self._order if i not in chosen]
        self._order = deque(first + rest)
        self._neighbours_first = True

    def resume(self, keep: int) -> None:
        """Identification goes on from landmark `keep` alone (the others were dropped)."""
        self._all_requested = False
        known = set(self._order)
        self._order.extend(i for i in self._all_ids if i not in known and i != keep)

    def _probe_request(self, lid: int) -> LedRequest:
        if self.config.probe == "light_one":
            return LedRequest(lit=frozenset({lid}))
        return LedRequest(all_lit=True, dark=frozenset({lid}))

    def _start(self, lid: int, t_ns: int, progress: Progress) -> LedRequest:
        self.current = lid
        self._since_ns = t_ns
        self._frames = 0
        self._in_force = False
        self._flight_seen = False
        self._shown_at_start = progress.probed.get(lid, 0)
        self._tried.add(lid)
        return self._probe_request(lid)

    def _one_sided(self, progress: Progress) -> int | None:
        """A landmark that showed itself on one side only and is lit now (darken_one)."""
        if self.config.probe != "darken_one":
            return None
        for lid in progress.unpaired:
            if (
                lid in self._lit_now
                and lid not in progress.identified
                and self._reprobed_at.get(lid) != progress.shown.get(lid, 0)
                and self._reprobes.get(lid, 0) < self.config.max_reprobes
            ):
                self._reprobes[lid] = self._reprobes.get(lid, 0) + 1
                self._reprobed_at[lid] = progress.shown.get(lid, 0)
                return lid
        return None

    def next_request(self, t_ns: int, progress: Progress) -> LedRequest | None:
        """The LED state to ask for now, or None to keep the current one."""
        cfg = self.config
        if progress.done:
            if self._all_requested:
                return None
            self._all_requested = True
            return LedRequest(all_lit=True)
        if cfg.probe == "light_one" and not self._dark_requested:
            self._dark_requested = True
            self._since_ns = t_ns
            return LedRequest(lit=frozenset())
        cur = self.current
        waited = 0.0 if self._since_ns is None else (t_ns - self._since_ns) * _NS
        if cur is not None:
            finished = (
                progress.probed.get(cur, 0) > self._shown_at_start
                or self._frames >= cfg.frames_per_led
                or waited > cfg.led_timeout_s
            )
            if not finished:
                return None
        elif cfg.probe == "light_one" and not self._dark_seen and waited <= cfg.led_timeout_s:
            return None  # no frame yet under the dark state
        again = self._one_sided(progress)
        if again is not None:
            return self._start(again, t_ns, progress)
        self._try_neighbours_first(progress)
        unpaired = set(progress.unpaired)
        while self._order and (
            self._order[0] in progress.identified
            or (
                self._order[0] not in unpaired
                and self._dark_frames.get(self._order[0], 0) >= cfg.frames_per_led
            )
        ):
            self._order.popleft()  # identified, or already probed (by another robot too)
        if not self._order:
            # Every candidate tried: start over (the robot may have moved).
            self._order = deque(i for i in self._all_ids if i not in progress.identified)
            self._neighbours_first = False
            self._dark_frames = {}
            self._tried = set()
            self._reprobes = {}
            self.current = None
            self._since_ns = t_ns
            if cfg.probe == "light_one":
                self._dark_requested = self._dark_seen = False
                return self.next_request(t_ns, progress)
            return LedRequest(all_lit=True)  # relight the last candidate (its evidence)
        return self._start(self._order.popleft(), t_ns, progress)

    def _try_neighbours_first(self, progress: Progress) -> None:
        """Once a landmark has shown itself, try the candidates nearest to it first."""
        if self._neighbours_first or progress.newest is None:
            return
        centre = self._xy.get(progress.newest)
        if centre is None:
            return
        self._neighbours_first = True
        rest = sorted(
            self._order,
            key=lambda i: float(np.hypot(*(self._xy.get(i, centre + 1e9) - centre))),
        )
        self._order = deque(rest)
