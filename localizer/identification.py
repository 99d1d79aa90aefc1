"""Landmark identification (Sec. III-A): with exactly one landmark lit, a new spot is that one.

The identifier watches frames together with the LED state in force when each was taken (from
`LedsChanged` events, whoever caused them). A spot seen while landmark L alone is lit is taken
for L only if it was absent from a frame in which L was dark (a reference frame before it or,
when there is none yet, the next one after it): a stray IR source that is always on, or a
sunlit reflection, is present in both and never taken. Among the new spots the brightest is L
(a reflection of L's own LED is fainter than its direct image).

In live use the identifier also chooses what to light next (`next_request`): first nothing
(a dark reference), then one landmark at a time, candidates near a prior pose first, until
`landmarks_needed` are identified; then all. A landmark that shows no new spot within
`frames_per_led` frames, or whose LED change is not confirmed within `led_timeout_s` (a dead
battery, out of radio range, out of view), is skipped.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.events import LedRequest

FloatArray = npt.NDArray[np.float64]

_NS = 1e-9


@dataclass(frozen=True)
class IdentificationConfig:
    """Tuning of identification.

    Attributes:
        landmarks_needed: identify this many, then light all (2 in the paper).
        frames_per_led: frames with a landmark lit alone without a new spot before it is
            skipped.
        led_timeout_s: a requested LED change not confirmed within this is skipped, seconds.
        match_radius_px: a spot within this of a spot of the reference frame (plus the image
            motion in between) is the same source, pixels.
        reference_max_age_s: reference frames older than this are not used, seconds.
        history_frames: frames kept for references.
    """

    landmarks_needed: int = 2
    frames_per_led: int = 2
    led_timeout_s: float = 0.5
    match_radius_px: float = 3.0
    reference_max_age_s: float = 0.5
    history_frames: int = 8

    def __post_init__(self) -> None:
        if self.landmarks_needed < 2 or self.frames_per_led < 1 or self.history_frames < 2:
            raise ValueError(
                "IdentificationConfig: landmarks_needed >= 2, frames_per_led >= 1, "
                "history_frames >= 2"
            )


@dataclass(frozen=True)
class Sighting:
    """A landmark identified in one frame: its spot at `pixel` (col, row) at `t_ns`."""

    landmark_id: int
    t_ns: int
    pixel: tuple[float, float]


@dataclass(frozen=True, eq=False)
class _Frame:
    t_ns: int
    lit: frozenset[int] | None  # None: all lit
    pixels: FloatArray
    intensities: FloatArray


class Identifier:
    """One-at-a-time identification from LED states and frames (sans-I/O).

    Args:
        config: tuning.
        landmark_ids: the map's landmark IDs (the default candidate order).
        motion_px: bound on the image motion of a spot between two times (ns), pixels;
            widens the match radius between a frame and its reference. The localizer derives
            it from odometry (or from the maximum speed when it has none).
    """

    def __init__(
        self,
        config: IdentificationConfig,
        landmark_ids: Sequence[int],
        *,
        motion_px: Callable[[int, int], float],
    ) -> None:
        self.config = config
        self._all_ids = [int(i) for i in landmark_ids]
        self._motion_px = motion_px
        self._history: deque[_Frame] = deque(maxlen=config.history_frames)
        self._pending: list[_Frame] = []
        self.sightings: dict[int, Sighting] = {}
        self.restart(self._all_ids)

    # -- what was seen -------------------------------------------------------------------------
    def restart(self, order: Sequence[int]) -> None:
        """Forget the identified landmarks and try the candidates in `order`."""
        self.sightings = {}
        self._verified: set[int] = set()
        self._pending = []
        self._order = deque(int(i) for i in order)
        self._frames_in_state = 0
        self._current: int | None = None
        self._current_since_ns: int | None = None
        self._current_frames = 0
        self._dark_requested = False
        self._all_requested = False

    @property
    def done(self) -> bool:
        """Enough landmarks identified."""
        return len(self.sightings) >= self.config.landmarks_needed

    def observe(
        self,
        t_ns: int,
        lit: frozenset[int] | None,
        pixels: FloatArray,
        intensities: FloatArray,
    ) -> list[Sighting]:
        """Take one frame's spots with the LED state it was taken under.

        Args:
            lit: IDs lit alone-or-together at the frame's time; None when all are lit.
            pixels: spot centres, shape (N, 2); intensities: shape (N,).

        Returns:
            The landmarks newly identified by this frame (possibly from an earlier, pending
            frame that this one verifies).
        """
        frame = _Frame(t_ns, lit, np.asarray(pixels, float).reshape(-1, 2), np.asarray(intensities))
        self._verify(frame)
        new: list[Sighting] = []
        still: list[_Frame] = []
        for p in self._pending:
            (lid,) = p.lit or frozenset({-1})
            if frame.lit is not None and lid not in frame.lit:
                s = self._identify(p, lid, frame)
                if s is not None:
                    new.append(s)
                    self._verified.add(lid)
            elif (t_ns - p.t_ns) * _NS <= self.config.reference_max_age_s:
                still.append(p)
        self._pending = still
        if lit is not None and len(lit) == 1:
            (lid,) = lit
            if lid == self._current:
                self._current_frames += 1
            if lid not in self.sightings and len(frame.pixels):
                ref = self._reference(lid, t_ns)
                if ref is None:
                    self._pending.append(frame)
                else:
                    s = self._identify(frame, lid, ref)
                    if s is not None:
                        new.append(s)
        self._history.append(frame)
        self._frames_in_state += 1
        for s in new:
            self.sightings[s.landmark_id] = s
        return new

    def _verify(self, frame: _Frame) -> None:
        """Drop sightings whose spot is still there in a frame where their LED is dark
        (a blinking stray source that happened to light with the LED)."""
        if frame.lit is None:
            return
        for lid, s in list(self.sightings.items()):
            if lid in frame.lit or lid in self._verified:
                continue
            radius = self.config.match_radius_px + self._motion_px(s.t_ns, frame.t_ns)
            d = np.hypot(frame.pixels[:, 0] - s.pixel[0], frame.pixels[:, 1] - s.pixel[1])
            if len(d) and float(d.min()) <= radius:
                del self.sightings[lid]
            else:
                self._verified.add(lid)

    def _reference(self, lid: int, t_ns: int) -> _Frame | None:
        for f in reversed(self._history):
            if (t_ns - f.t_ns) * _NS > self.config.reference_max_age_s:
                return None
            if f.lit is not None and lid not in f.lit:
                return f
        return None

    def _identify(self, frame: _Frame, lid: int, ref: _Frame) -> Sighting | None:
        """The brightest spot of `frame` absent from `ref`, as landmark `lid`."""
        if len(frame.pixels) == 0:
            return None
        fresh = np.ones(len(frame.pixels), dtype=bool)
        if len(ref.pixels):
            radius = self.config.match_radius_px + self._motion_px(ref.t_ns, frame.t_ns)
            d = np.hypot(
                frame.pixels[:, None, 0] - ref.pixels[None, :, 0],
                frame.pixels[:, None, 1] - ref.pixels[None, :, 1],
            )
            fresh = d.min(axis=1) > radius
        if not fresh.any():
            return None
        k = int(np.flatnonzero(fresh)[np.argmax(frame.intensities[fresh])])
        px = frame.pixels[k]
        return Sighting(lid, frame.t_ns, (float(px[0]), float(px[1])))

    # -- what to light next (live use) ---------------------------------------------------------
    def led_confirmed(self, t_ns: int, lit: frozenset[int] | None) -> None:
        """Note an LED change (restarts the frame count of the current candidate)."""
        self._frames_in_state = 0
        if lit is not None and self._current is not None and lit == frozenset({self._current}):
            self._current_since_ns = t_ns
            self._current_frames = 0

    def next_request(self, t_ns: int) -> LedRequest | None:
        """The LED state to ask for now, or None to keep the current one."""
        cfg = self.config
        if self.done:
            if self._all_requested:
                return None
            self._all_requested = True
            return LedRequest(all_lit=True)
        if not self._dark_requested:
            self._dark_requested = True
            self._current_since_ns = t_ns
            return LedRequest(lit=frozenset())
        cur = self._current
        if cur is not None:
            waited = (t_ns - (self._current_since_ns or t_ns)) * _NS
            finished = (
                cur in self.sightings
                or self._current_frames >= cfg.frames_per_led
                or waited > cfg.led_timeout_s
            )
            if not finished:
                return None
        elif self._frames_in_state < 1 and (t_ns - (self._current_since_ns or t_ns)) * _NS <= (
            cfg.led_timeout_s
        ):
            return None  # no frame yet under the dark state
        if not self._order:
            # Every candidate tried: start over (the robot may have moved), dark frame first.
            self._order = deque(i for i in self._all_ids if i not in self.sightings)
            self._dark_requested = False
            self._current = None
            return self.next_request(t_ns)
        nxt = self._order.popleft()
        while nxt in self.sightings and self._order:
            nxt = self._order.popleft()
        self._current = nxt
        self._current_since_ns = t_ns
        self._current_frames = 0
        return LedRequest(lit=frozenset({nxt}))
