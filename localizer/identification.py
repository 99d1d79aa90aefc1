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

Each sighting carries the raw odometry pose of its frame (`Sighting.odometry`): a sighting
is a ray from a known odometry pose, carried to any later time however old it is
(`first_fix.py`). Evidence that did not pair within `2 reference_max_age_s` can no longer
pair and is dropped; the newest is remembered (`anchor`) to order the candidates.

In live use the identifier also chooses what to light next (`next_request`, the probe plan
of `localizer/probing.py`). When identified landmarks do not give a consistent fix, the
newest is kept (`keep_newest`: a fresh sighting near the robot) and the others dropped.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass

import numpy as np

from localizer.events import LedRequest
from localizer.identification_config import IdentificationConfig, Probe
from localizer.probing import ProbePlan, Progress
from localizer.types import FloatArray

OdometryPose = tuple[float, float, float]

_NS = 1e-9

__all__ = ["Evidence", "IdentificationConfig", "Identifier", "Probe", "Sighting"]


@dataclass(frozen=True)
class Sighting:
    """A landmark identified in one frame: its spot at `pixel` (col, row) at `t_ns`, seen
    from the raw odometry pose `odometry` (x, y, theta; None: unknown, look it up)."""

    landmark_id: int
    t_ns: int
    pixel: tuple[float, float]
    odometry: OdometryPose | None = None


@dataclass(frozen=True)
class Evidence:
    """One switch of landmark `landmark_id` seen between two frames.

    Attributes:
        appeared: the spot appeared when the LED was lit (else it vanished when darkened).
        t_ns, pixel: the frame in which the landmark was lit, and its spot there.
        alone: the landmark was the only LED lit in that frame.
        odometry: the raw odometry pose at `t_ns`, if known.
    """

    landmark_id: int
    appeared: bool
    t_ns: int
    pixel: tuple[float, float]
    alone: bool
    odometry: OdometryPose | None = None


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
        odometry_at: the raw odometry pose at a time (ns), stored with each piece of
            evidence (None: not stored).
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
        odometry_at: Callable[[int], OdometryPose] | None = None,
    ) -> None:
        self.config = config
        self._all_ids = [int(i) for i in landmark_ids]
        self.all_lit = frozenset(self._all_ids)
        self.probes = ProbePlan(config, self._all_ids, positions)
        self._centre: tuple[float, float] | None = None
        self._inner_px = np.inf
        if image_size is not None:
            w, h = image_size
            cu, cv = principal_point or ((w - 1) / 2, (h - 1) / 2)
            self._centre = (cu, cv)
            self._inner_px = config.inner_radius_fraction * min(cu, cv, w - 1 - cu, h - 1 - cv)
        self._motion_px = motion_px
        self._odometry_at = odometry_at
        self._history: deque[_Frame] = deque(maxlen=config.history_frames)
        self.sightings: dict[int, Sighting] = {}
        self.evidence: dict[int, list[Evidence]] = {}
        self.restart(self._all_ids)

    def restart(self, order: Sequence[int]) -> None:
        """Forget the identified landmarks and try the candidates in `order`."""
        self.sightings = {}
        self.evidence = {}
        self._shown: dict[int, int] = {}  # pieces of evidence per landmark (only grow)
        self._probed: dict[int, int] = {}  # ... of the probe's kind (darken_one: vanished)
        self._newest: Evidence | None = None  # the first of the newest unpaired episode
        self.probes.restart(order)

    @property
    def inner_radius_px(self) -> float:
        """Changed spots farther than this from the principal point are not used, pixels."""
        return self._inner_px

    @property
    def anchor(self) -> Sighting | None:
        """What the candidate order can start from: the one landmark identified, or before
        any, the first piece of the newest evidence (kept after it expired); None with two
        or more identified, or nothing."""
        if len(self.sightings) == 1:
            return next(iter(self.sightings.values()))
        if self.sightings or self._newest is None:
            return None
        ev = self._newest
        return Sighting(ev.landmark_id, ev.t_ns, ev.pixel, ev.odometry)

    def prefer(self, order: Sequence[int], *, come_into_view: Collection[int] = ()) -> None:
        """Try the candidates in `order` next (`ProbePlan.prefer`), never identified ones."""
        self.probes.prefer(
            [int(i) for i in order if int(i) not in self.sightings], come_into_view=come_into_view
        )

    def keep_newest(self) -> None:
        """Keep only the newest sighting (and its evidence): the others disagreed with it."""
        if not self.sightings:
            return
        newest = max(self.sightings.values(), key=lambda s: s.t_ns)
        self.sightings = {newest.landmark_id: newest}
        self.evidence = {newest.landmark_id: self.evidence.get(newest.landmark_id, [])}
        self.probes.resume(newest.landmark_id)

    @property
    def done(self) -> bool:
        """Enough landmarks identified."""
        return len(self.sightings) >= self.config.landmarks_needed

    # -- what to light next (live use) ---------------------------------------------------------
    def led_confirmed(self, t_ns: int, lit: frozenset[int] | None) -> None:
        """Note an LED state (None: unknown, a switch in flight); `ProbePlan.led_confirmed`."""
        self.probes.led_confirmed(t_ns, lit)

    def next_request(self, t_ns: int) -> LedRequest | None:
        """The LED state to ask for now, or None to keep the current one."""
        unpaired = sorted(
            (lid for lid in self.evidence if lid not in self.sightings),
            key=lambda lid: -self.evidence[lid][-1].t_ns,
        )
        shown = [e for seen in self.evidence.values() for e in seen[-1:]]
        newest = max(shown, key=lambda e: e.t_ns).landmark_id if shown else None
        progress = Progress(
            self.sightings.keys(), self._shown, self._probed, unpaired, newest, self.done
        )
        return self.probes.next_request(t_ns, progress)

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
        self._drop_expired(t_ns)
        self.probes.note_frame(frame.lit)
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
        odometry = None if self._odometry_at is None else self._odometry_at(lit_frame.t_ns)
        alone = lit_frame.lit == frozenset({lid})
        return Evidence(lid, appeared, lit_frame.t_ns, pixel, alone, odometry)

    def _add_evidence(self, ev: Evidence) -> Sighting | None:
        """Keep `ev` (once: the same switch is seen against several reference frames); the
        sighting it completes, if any."""
        seen = self.evidence.setdefault(ev.landmark_id, [])
        if not any(e.appeared == ev.appeared and e.t_ns == ev.t_ns for e in seen):
            if not seen:
                self._newest = ev  # a new episode of this landmark's evidence
            seen.append(ev)
            self._shown[ev.landmark_id] = self._shown.get(ev.landmark_id, 0) + 1
            if ev.appeared == (self.config.probe == "light_one"):
                self._probed[ev.landmark_id] = self._probed.get(ev.landmark_id, 0) + 1
        confirmed = ev.alone or any(
            e.appeared != ev.appeared
            and self._same_place(e.pixel, e.t_ns, ev.pixel, ev.t_ns)
            and self._follows_its_led(ev.landmark_id, (e, ev))
            for e in seen
        )
        if not confirmed:
            return None
        s = Sighting(ev.landmark_id, ev.t_ns, ev.pixel, ev.odometry)
        self.sightings[ev.landmark_id] = s
        return s

    def _drop_expired(self, t_ns: int) -> None:
        """Drop unpaired evidence too old to pair with any to come (a new piece is at most
        `reference_max_age_s` older than its frame, and pairs within twice that)."""
        horizon = t_ns - 3 * self.config.reference_max_age_s / _NS
        for lid, seen in list(self.evidence.items()):
            if lid not in self.sightings and seen and seen[-1].t_ns < horizon:
                del self.evidence[lid]

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
