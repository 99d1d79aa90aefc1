"""Landmark identification (Sec. III-A) from LED switches, whoever switched them.

The paper lights one landmark at a time against a dark ceiling: a new spot is that landmark.
We generalise it to any single switch, so that one robot can identify itself while the
others go on tracking: between two frames whose LED states differ in exactly one landmark L
(L lit in one, dark in the other, every other LED the same), the one spot present in the
lit frame and absent from the dark one (after the image motion in between) is L. The
paper's sweep (all dark, then {L1}, then {L2}, ...) is one instance; darkening one landmark
of a lit ceiling at a time is another (`probe="darken_one"`, the default in live use: the
other robots lose one landmark for a few frames instead of all of them).

Each such pair of frames is one piece of *evidence*: "L appeared" or "L vanished", at a
pixel and time. A landmark is identified by
- one piece of evidence from a frame where L was the only LED lit (the paper's case: any
  new spot is L), or
- two opposite pieces (it vanished when darkened and came back when relit) at the same
  place, after the image motion in between (against a lit ceiling: a landmark leaving the
  view, or a person walking under it, can look like a switch once, not twice in opposite
  ways at the same place).
Frames taken while a switch is in flight (state unknown) are never used. Changed spots
towards the edge of the view or faint ones are not used (there, spots fade in and out as the
robot moves, and flicker at the detection threshold), and when
several spots changed, the brightest is taken only when it is `unique_brightness_ratio`
times brighter than the next (a reflection of L's own LED is fainter than its direct
image); otherwise the pair is ambiguous and ignored. An identified landmark whose spot is
still there in a frame with its LED dark is dropped (a blinking stray IR source that
happened to switch with it).

In live use the identifier also chooses what to light next (`next_request`): one landmark
at a time, candidates near a prior pose first, and once one landmark has shown itself,
those near it (they are the ones in view); a landmark that shows nothing within
`frames_per_led` frames, or whose switch is not confirmed within `led_timeout_s` (a dead
battery, out of radio range, out of view), is skipped. When `landmarks_needed` are
identified it asks for every LED lit.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from localizer.events import LedRequest

FloatArray = npt.NDArray[np.float64]

_NS = 1e-9

Probe = Literal["darken_one", "light_one"]


@dataclass(frozen=True)
class IdentificationConfig:
    """Tuning of identification.

    Attributes:
        landmarks_needed: identify this many, then light all (2 in the paper).
        probe: what `next_request` asks for: "darken_one" (every LED lit but the
            candidate: other robots keep tracking) or "light_one" (the paper: a dark
            ceiling with the candidate alone lit).
        frames_per_led: frames with a candidate switched without evidence before it is
            skipped.
        led_timeout_s: a requested LED change not confirmed within this is skipped, seconds.
        match_radius_px: a spot within this of a spot of the other frame (plus the image
            motion in between) is the same source, pixels.
        inner_radius_fraction: only changed spots within this fraction of the distance from
            the principal point to the nearest image edge are used (at the edge of the view,
            spots fade in and out with the robot's motion and flicker at the threshold),
            minus the image motion.
        min_relative_intensity: only changed spots at least this bright relative to the
            median spot of their frame are used (a faint spot flickers at the threshold).
        unique_brightness_ratio: with several changed spots, the brightest is taken only
            when it is this many times brighter than the next.
        reference_max_age_s: frames further apart than this are not compared, seconds.
        follow_window_s: a sighting against a lit ceiling is confirmed only if the spot
            followed its LED in every kept frame from this long before its first piece of
            evidence to this long after its last, seconds.
        history_frames: frames kept for comparisons.
    """

    landmarks_needed: int = 2
    probe: Probe = "darken_one"
    frames_per_led: int = 2
    led_timeout_s: float = 0.5
    match_radius_px: float = 3.0
    inner_radius_fraction: float = 0.8
    min_relative_intensity: float = 0.5
    unique_brightness_ratio: float = 2.0
    reference_max_age_s: float = 0.5
    follow_window_s: float = 0.1
    history_frames: int = 24

    def __post_init__(self) -> None:
        if self.landmarks_needed < 2 or self.frames_per_led < 1 or self.history_frames < 2:
            raise ValueError(
                "IdentificationConfig: landmarks_needed >= 2, frames_per_led >= 1, "
                "history_frames >= 2"
            )
        if self.probe not in ("darken_one", "light_one"):
            raise ValueError(
                f"IdentificationConfig.probe: 'darken_one' or 'light_one', got {self.probe!r}"
            )
        if self.unique_brightness_ratio < 1.0:
            raise ValueError(
                "IdentificationConfig.unique_brightness_ratio must be >= 1, "
                f"got {self.unique_brightness_ratio}"
            )


@dataclass(frozen=True)
class Sighting:
    """A landmark identified in one frame: its spot at `pixel` (col, row) at `t_ns`."""

    landmark_id: int
    t_ns: int
    pixel: tuple[float, float]


@dataclass(frozen=True)
class Evidence:
    """One switch of landmark `landmark_id` seen between two frames.

    Attributes:
        appeared: the spot appeared when the LED was lit (else it vanished when darkened).
        t_ns, pixel: the frame in which the landmark was lit, and its spot there.
        alone: the landmark was the only LED lit in that frame.
    """

    landmark_id: int
    appeared: bool
    t_ns: int
    pixel: tuple[float, float]
    alone: bool


@dataclass(frozen=True, eq=False)
class _Frame:
    t_ns: int
    lit: frozenset[int] | None  # None: unknown (a switch in flight)
    pixels: FloatArray
    intensities: FloatArray


class Identifier:
    """Identification from LED switches and frames (sans-I/O).

    Args:
        config: tuning.
        landmark_ids: the map's landmark IDs (the default candidate order).
        positions: the landmarks' world positions, shape (N, 3), in the order of
            `landmark_ids` (to try a found landmark's neighbours next).
        image_size: (width, height) of the frames, pixels.
        principal_point: (cu, cv), pixels; the image centre when not given.
        motion_px: bound on the image motion of a spot between two times (ns), pixels;
            widens the match radius between two frames. The localizer derives it from
            odometry (or from the maximum speed when it has none).
    """

    def __init__(
        self,
        config: IdentificationConfig,
        landmark_ids: Sequence[int],
        *,
        positions: FloatArray | None = None,
        image_size: tuple[int, int] | None = None,
        principal_point: tuple[float, float] | None = None,
        motion_px: Callable[[int, int], float],
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
        self._centre: tuple[float, float] | None = None
        self._inner_px = np.inf
        if image_size is not None:
            w, h = image_size
            cu, cv = principal_point or ((w - 1) / 2, (h - 1) / 2)
            self._centre = (cu, cv)
            self._inner_px = config.inner_radius_fraction * min(cu, cv, w - 1 - cu, h - 1 - cv)
        self._motion_px = motion_px
        self._history: deque[_Frame] = deque(maxlen=config.history_frames)
        self.sightings: dict[int, Sighting] = {}
        self.evidence: dict[int, list[Evidence]] = {}
        self.restart(self._all_ids)

    def restart(self, order: Sequence[int]) -> None:
        """Forget the identified landmarks and try the candidates in `order`."""
        self.sightings = {}
        self.evidence = {}
        self._order = deque(int(i) for i in order)
        self._current: int | None = None
        self._current_since_ns: int | None = None
        self._current_frames = 0
        self._in_force = False
        self._dark_requested = False
        self._dark_seen = False
        self._all_requested = False
        self._neighbours_first = False
        self._dark_frames: dict[int, int] = {}  # frames seen with only this one darkened

    @property
    def done(self) -> bool:
        """Enough landmarks identified."""
        return len(self.sightings) >= self.config.landmarks_needed

    # -- what was seen -------------------------------------------------------------------------
    def observe(
        self,
        t_ns: int,
        lit: frozenset[int] | None,
        pixels: FloatArray,
        intensities: FloatArray,
    ) -> list[Sighting]:
        """Take one frame's spots with the LED state it was taken under.

        Args:
            lit: IDs lit at the frame's time (all of them when every LED is lit); None when
                the state is unknown (a switch in flight).
            pixels: spot centres, shape (N, 2); intensities: shape (N,).

        Returns:
            The landmarks newly identified by this frame.
        """
        frame = _Frame(
            t_ns,
            None if lit is None else frozenset(lit),
            np.asarray(pixels, float).reshape(-1, 2),
            np.asarray(intensities, float).reshape(-1),
        )
        if frame.lit is None:
            return []
        self._drop_contradicted(frame)
        self._note_candidate(frame)
        new: list[Sighting] = []
        compared: set[frozenset[int]] = set()
        earlier = list(self._history)
        self._history.append(frame)
        for ref in reversed(earlier):
            if (t_ns - ref.t_ns) * _NS > self.config.reference_max_age_s:
                break
            if ref.lit is None or ref.lit in compared or ref.lit == frame.lit:
                continue
            compared.add(ref.lit)
            for lit_frame, dark_frame, appeared in ((frame, ref, True), (ref, frame, False)):
                switched = (lit_frame.lit or frozenset()) - (dark_frame.lit or frozenset())
                if len(switched) != 1:
                    continue
                (lid,) = switched
                if lid in self.sightings:
                    continue
                ev = self._evidence(lid, lit_frame, dark_frame, appeared)
                if ev is not None:
                    s = self._add_evidence(ev)
                    if s is not None:
                        new.append(s)
        return new

    def _evidence(
        self, lid: int, lit_frame: _Frame, dark_frame: _Frame, appeared: bool
    ) -> Evidence | None:
        """The one spot of `lit_frame` absent from `dark_frame`, as evidence for `lid`."""
        pixels, inten = lit_frame.pixels, lit_frame.intensities
        if len(pixels) == 0:
            return None
        motion = self._motion_px(dark_frame.t_ns, lit_frame.t_ns)
        changed = np.ones(len(pixels), dtype=bool)
        if len(dark_frame.pixels):
            d = np.hypot(
                pixels[:, None, 0] - dark_frame.pixels[None, :, 0],
                pixels[:, None, 1] - dark_frame.pixels[None, :, 1],
            )
            changed = d.min(axis=1) > self.config.match_radius_px + motion
        if self._centre is not None:
            radius = np.hypot(pixels[:, 0] - self._centre[0], pixels[:, 1] - self._centre[1])
            changed &= radius <= self._inner_px - motion
        changed &= inten >= self.config.min_relative_intensity * float(np.median(inten))
        idx = np.flatnonzero(changed)
        if len(idx) == 0:
            return None
        order = idx[np.argsort(-inten[idx], kind="stable")]
        if len(order) > 1 and inten[order[0]] < self.config.unique_brightness_ratio * max(
            float(inten[order[1]]), 0.0
        ):
            return None  # ambiguous: two sources switched with it
        k = int(order[0])
        pixel = (float(pixels[k, 0]), float(pixels[k, 1]))
        return Evidence(lid, appeared, lit_frame.t_ns, pixel, lit_frame.lit == frozenset({lid}))

    def _add_evidence(self, ev: Evidence) -> Sighting | None:
        """Keep `ev`; the sighting it completes, if any."""
        seen = self.evidence.setdefault(ev.landmark_id, [])
        seen.append(ev)
        confirmed = ev.alone or any(
            e.appeared != ev.appeared
            and self._same_place(e.pixel, e.t_ns, ev.pixel, ev.t_ns)
            and self._follows_its_led(ev.landmark_id, (e, ev))
            for e in seen[:-1]
        )
        if not confirmed:
            return None
        s = Sighting(ev.landmark_id, ev.t_ns, ev.pixel)
        self.sightings[ev.landmark_id] = s
        return s

    def _same_place(
        self, a: tuple[float, float], t_a: int, b: tuple[float, float], t_b: int
    ) -> bool:
        if abs(t_a - t_b) * _NS > 2 * self.config.reference_max_age_s:
            return False
        radius = self.config.match_radius_px + self._motion_px(t_a, t_b)
        return bool(np.hypot(a[0] - b[0], a[1] - b[1]) <= radius)

    def _follows_its_led(self, lid: int, evidence: tuple[Evidence, Evidence]) -> bool:
        """Whether the spot was there in every kept frame around the evidence with the LED
        lit, and in none with it dark (a stray source that flickers, or a landmark at the
        threshold, matches the switches only now and then)."""
        t0 = min(e.t_ns for e in evidence) - self.config.follow_window_s / _NS
        t1 = max(e.t_ns for e in evidence) + self.config.follow_window_s / _NS
        for f in self._history:
            if f.lit is None or not t0 <= f.t_ns <= t1:
                continue
            ref = min(evidence, key=lambda e: abs(e.t_ns - f.t_ns))
            radius = self.config.match_radius_px + self._motion_px(ref.t_ns, f.t_ns)
            d = np.hypot(f.pixels[:, 0] - ref.pixel[0], f.pixels[:, 1] - ref.pixel[1])
            present = bool(len(d)) and float(d.min()) <= radius
            if present != (lid in f.lit):
                return False
        return True

    def _drop_contradicted(self, frame: _Frame) -> None:
        """Drop sightings whose spot is still there, soon after, with their LED dark."""
        lit = frame.lit or frozenset()
        for lid, s in list(self.sightings.items()):
            if lid in lit or (frame.t_ns - s.t_ns) * _NS > self.config.reference_max_age_s:
                continue
            radius = self.config.match_radius_px + self._motion_px(s.t_ns, frame.t_ns)
            d = np.hypot(frame.pixels[:, 0] - s.pixel[0], frame.pixels[:, 1] - s.pixel[1])
            if len(d) and float(d.min()) <= radius:
                del self.sightings[lid]
                self.evidence.pop(lid, None)

    # -- what to light next (live use) ---------------------------------------------------------
    def _probe_in_force(self, lit: frozenset[int]) -> bool:
        cur = self._current
        if cur is None:
            return False
        if self.config.probe == "light_one":
            return lit == frozenset({cur})
        return cur not in lit

    def _note_candidate(self, frame: _Frame) -> None:
        lit = frame.lit or frozenset()
        if self.config.probe == "light_one" and not lit:
            self._dark_seen = True
        if self._probe_in_force(lit):
            self._current_frames += 1
        dark = self.all_lit - lit
        if len(dark) == 1:  # someone's darken probe: no need to ask for it again
            (lid,) = dark
            self._dark_frames[lid] = self._dark_frames.get(lid, 0) + 1

    def led_confirmed(self, t_ns: int, lit: frozenset[int] | None) -> None:
        """Note an LED state (None: unknown, a switch in flight): the candidate's frame count
        starts when its probe is in force."""
        in_force = lit is not None and self._probe_in_force(lit)
        if in_force and not self._in_force:
            self._current_since_ns = t_ns
            self._current_frames = 0
        self._in_force = in_force

    def _probe_request(self, lid: int) -> LedRequest:
        if self.config.probe == "light_one":
            return LedRequest(lit=frozenset({lid}))
        return LedRequest(all_lit=True, dark=frozenset({lid}))

    def next_request(self, t_ns: int) -> LedRequest | None:
        """The LED state to ask for now, or None to keep the current one."""
        cfg = self.config
        if self.done:
            if self._all_requested:
                return None
            self._all_requested = True
            return LedRequest(all_lit=True)
        if cfg.probe == "light_one" and not self._dark_requested:
            self._dark_requested = True
            self._current_since_ns = t_ns
            return LedRequest(lit=frozenset())
        cur = self._current
        waited = (t_ns - (self._current_since_ns or t_ns)) * _NS
        if cur is not None:
            finished = (
                cur in self.evidence
                or self._current_frames >= cfg.frames_per_led
                or waited > cfg.led_timeout_s
            )
            if not finished:
                return None
        elif cfg.probe == "light_one" and not self._dark_seen and waited <= cfg.led_timeout_s:
            return None  # no frame yet under the dark state
        self._try_neighbours_first()
        while self._order and (
            self._order[0] in self.sightings
            or (
                self._order[0] not in self.evidence
                and self._dark_frames.get(self._order[0], 0) >= cfg.frames_per_led
            )
        ):
            self._order.popleft()  # identified, or already probed (by another robot too)
        if not self._order:
            # Every candidate tried: start over (the robot may have moved).
            self._order = deque(i for i in self._all_ids if i not in self.sightings)
            self._neighbours_first = False
            self._dark_frames = {}
            self._current = None
            self._current_since_ns = t_ns
            if cfg.probe == "light_one":
                self._dark_requested = self._dark_seen = False
                return self.next_request(t_ns)
            return LedRequest(all_lit=True)  # relight the last candidate (its evidence)
        nxt = self._order.popleft()
        self._current = nxt
        self._current_since_ns = t_ns
        self._current_frames = 0
        self._in_force = False
        return self._probe_request(nxt)

    def _try_neighbours_first(self) -> None:
        """Once a landmark has shown itself, try the candidates nearest to it first."""
        if self._neighbours_first or not self.evidence:
            return
        found = next(iter(self.evidence))
        centre = self._xy.get(found)
        if centre is None:
            return
        self._neighbours_first = True
        rest = sorted(
            self._order,
            key=lambda i: float(np.hypot(*(self._xy.get(i, centre + 1e9) - centre))),
        )
        self._order = deque(rest)
