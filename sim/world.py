"""The virtual building: landmarks (true and surveyed positions, LEDs, batteries, radios),
other IR sources (lamps, sunlight, glints) and people walking under the landmarks.

The world is advanced by its owner (`VirtualSite` or the offline simulator) with `advance(t_ns)`;
the simulated radio switches LEDs from another thread, so LED state sits behind a lock.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from lighting.battery import Battery
from lighting.energy import EnergyLedger
from localizer.types import BoolArray, FloatArray
from sim.render import ExtendedSource

IN_LIFT = "\x00lift"
"""`point_sources(floor=IN_LIFT)`: what a camera in the lift cabin sees (no landmark)."""


@dataclass
class SimLandmark:
    """One landmark as it really is.

    Attributes:
        id: landmark ID.
        p_true: the LED's true position, metres, shape (3,).
        p_surveyed: where the survey (map.json) puts it, metres, shape (3,).
        address: radio address, 16 hex digits.
        battery: its cells.
        radio_dead: the radio never answers (a broken landmark).
        led_on: the LED pin is high.
        led_dead: the LED never lights although the radio answers (a burnt-out LED).
        panel_size_m: a passive ceiling light's size (rendered as an extended source;
            map.json flags it `passive`), metres; 0: an LED.
        map_sigma_m: the position sigma map.json states for it, metres (None: none).
    """

    id: int
    p_true: FloatArray
    p_surveyed: FloatArray
    address: str
    battery: Battery
    radio_dead: bool = False
    led_on: bool = True
    led_dead: bool = False
    floor: str = "0"
    panel_size_m: float = 0.0
    map_sigma_m: float | None = None

    @property
    def node_id(self) -> str:
        return f"LM{self.id}"

    @property
    def reachable(self) -> bool:
        return not self.radio_dead and self.battery.alive


@dataclass(frozen=True)
class Glint:
    """A small non-landmark IR point source (a smoke detector's LED, a reflection).

    Attributes:
        p_world: position, metres, shape (3,).
        intensity: 1.0 = a nominal landmark LED.
        blink_period_s: 0 for steady, else on for the first half of each period.
    """

    p_world: tuple[float, float, float]
    intensity: float
    blink_period_s: float = 0.0


@dataclass(frozen=True)
class Person:
    """Someone walking back and forth along a path: a vertical cylinder that blocks rays.

    Attributes:
        path: corners of the walk, metres, shape (M, 2), walked there and back.
        speed_mps: walking speed.
        radius_m: the cylinder's radius; height_m: its height.
    """

    path: tuple[tuple[float, float], ...]
    speed_mps: float = 1.0
    radius_m: float = 0.25
    height_m: float = 1.8

    def position(self, t_s: float) -> FloatArray:
        """Where the person stands at `t_s`, shape (2,)."""
        pts = np.asarray(self.path, dtype=np.float64)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        total = float(seg.sum())
        if total == 0:
            return np.array(pts[0], dtype=np.float64)
        s = (t_s * self.speed_mps) % (2 * total)
        s = 2 * total - s if s > total else s
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        return np.array([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])

    def blocks(self, t_s: float, p_from: FloatArray, p_to: FloatArray) -> BoolArray:
        """Which segments p_from -> p_to[i] (shape (N, 3)) pass through the person."""
        c = self.position(t_s)
        a = np.asarray(p_from, dtype=np.float64)
        b = np.asarray(p_to, dtype=np.float64).reshape(-1, 3)
        # Clip each segment to the part below the person's height.
        dz = b[:, 2] - a[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s_top = np.where(dz > 1e-9, (self.height_m - a[2]) / dz, 1.0)
        s_top = np.clip(s_top, 0.0, 1.0)
        a2 = a[:2]
        d2 = (b[:, :2] - a2) * s_top[:, None]
        # Distance from c to the 2-D segment a2 -> a2 + d2.
        len2 = np.maximum((d2**2).sum(axis=1), 1e-12)
        s = np.clip(((c - a2) * d2).sum(axis=1) / len2, 0.0, 1.0)
        nearest = a2 + d2 * s[:, None]
        blocked: BoolArray = (np.linalg.norm(nearest - c, axis=1) < self.radius_m) & (
            a[2] < self.height_m
        )
        return blocked


@dataclass
class World:
    """Landmarks, other IR sources and occluders.

    Attributes:
        landmarks: by ID.
        glints: non-landmark point sources.
        extended: lamps and sunlight patches.
        people: occluders.
        t_ns: the time the world has been advanced to.
        energy: what each landmark's LED and radio draw (`lighting.energy`); None: the
            battery's own constant `idle_current_ma` for the radio.
    """

    landmarks: dict[int, SimLandmark]
    glints: list[Glint] = field(default_factory=list)
    extended: list[ExtendedSource] = field(default_factory=list)
    people: list[Person] = field(default_factory=list)
    t_ns: int = 0
    battery_step_s: float = 0.25
    led_clock_ns: Callable[[], int] | None = None
    led_log_s: float = 2.0
    energy: EnergyLedger | None = field(default_factory=EnergyLedger)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _battery_t_ns: int = 0
    _led_log: deque[tuple[int, int, bool]] = field(default_factory=deque, repr=False)

    def __post_init__(self) -> None:
        self._battery_t_ns = self.t_ns
        self._by_address = {lm.address: lm for lm in self.landmarks.values()}

    def by_address(self, address: str) -> SimLandmark | None:
        return self._by_address.get(address.upper())

    def set_led(self, landmark_id: int, on: bool) -> None:
        """Switch one landmark's LED pin (what a delivered radio command does).

        The switch is logged at `led_clock_ns()` (the world's time when there is no LED
        clock), so a frame can be rendered with the LEDs as they were at its own time.
        """
        with self._lock:
            lm = self.landmarks[landmark_id]
            if lm.led_on != on:
                t = self.led_clock_ns() if self.led_clock_ns is not None else self.t_ns
                self._led_log.append((t, landmark_id, lm.led_on))
            lm.led_on = on

    def _lit_at(self, t_ns: int | None) -> dict[int, bool]:
        """Each landmark's LED state at `t_ns` (now when None): the current state with the
        logged switches after `t_ns` undone. Call with the lock held."""
        state = {lid: lm.led_on for lid, lm in self.landmarks.items()}
        if t_ns is not None:
            for t, lid, before in reversed(self._led_log):
                if t <= t_ns:
                    break
                state[lid] = before
        return state

    def set_lit(self, lit: set[int] | None) -> None:
        """Light exactly `lit` (None: all) of the landmarks the radio reaches."""
        with self._lock:
            for lm in self.landmarks.values():
                if lm.reachable:
                    lm.led_on = lit is None or lm.id in lit

    def lit_ids(self) -> set[int]:
        with self._lock:
            return {lm.id for lm in self.landmarks.values() if lm.led_on}

    def advance(self, t_ns: int) -> None:
        """Advance people and batteries to `t_ns` (earlier times are ignored).

        Batteries discharge slowly: they are stepped once `battery_step_s` has gathered.
        """
        if t_ns <= self.t_ns:
            return
        self.t_ns = t_ns
        horizon = t_ns - round(self.led_log_s * 1e9)
        with self._lock:
            while self._led_log and self._led_log[0][0] < horizon:
                self._led_log.popleft()
        dt_s = (t_ns - self._battery_t_ns) * 1e-9
        if dt_s < self.battery_step_s:
            return
        with self._lock:
            for lm in self.landmarks.values():
                if self.energy is None:
                    lm.battery.advance(dt_s, lm.led_on)
                    continue
                led_ma = lm.battery.led_ma(lm.led_on)
                radio_mah = self.energy.advance(lm.id, dt_s, led_ma) if lm.battery.alive else 0.0
                lm.battery.draw(led_ma * dt_s / 3600.0 + radio_mah)
        self._battery_t_ns = t_ns

    def replace_cells(self, landmark_id: int) -> None:
        """Fresh cells in a landmark (what a technician does on a ladder): full charge, the
        same circuit; KeyError for an unknown landmark."""
        with self._lock:
            lm = self.landmarks[landmark_id]
            lm.battery = Battery(lm.battery.config)

    def radio_message(self, landmark_id: int, extra_awake_s: float = 0.0) -> None:
        """A command reached the landmark and it answered (and stays awake `extra_awake_s`
        longer than it would have; negative: shorter, after a shorter `ST`): account the
        radio's charge."""
        if self.energy is not None:
            with self._lock:
                q = self.energy.message(landmark_id, extra_awake_s)
                self.landmarks[landmark_id].battery.draw(q)

    def point_sources(
        self, p_camera_world: FloatArray, *, t_ns: int | None = None, floor: str | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Lit point sources seen from a camera position (people block them).

        Args:
            p_camera_world: the camera's optical centre, metres, shape (3,).
            t_ns: take the LEDs as they were at this time (on the LED clock, within the
                last `led_log_s`); None: as they are now.
            floor: only the landmarks of this floor (None: every landmark; `IN_LIFT`: none,
                nor any glint: the lift cabin's ceiling).

        Returns:
            (positions shape (N, 3), intensities shape (N,)), 1.0 = a nominal LED.
        """
        t_s = self.t_ns * 1e-9
        with self._lock:
            on = self._lit_at(t_ns)
            lit = [
                lm
                for lid, lm in self.landmarks.items()
                if on[lid] and not lm.led_dead and (floor is None or lm.floor == floor)
            ]
            pos = [lm.p_true for lm in lit]
            inten = [lm.battery.led_brightness() for lm in lit]
        for g in self.glints if floor != IN_LIFT else ():
            if g.blink_period_s <= 0 or (t_s % g.blink_period_s) < g.blink_period_s / 2:
                pos.append(np.asarray(g.p_world, dtype=np.float64))
                inten.append(g.intensity)
        p = np.array(pos, dtype=np.float64).reshape(-1, 3)
        i = np.array(inten, dtype=np.float64)
        for person in self.people:
            if len(p):
                i = np.where(person.blocks(t_s, p_camera_world, p), 0.0, i)
        return p, i

    def landmark_records(self) -> list[dict[str, object]]:
        """The surveyed map (map.json's `landmarks`), with each landmark's `radio` address."""
        out: list[dict[str, object]] = []
        for lm in sorted(self.landmarks.values(), key=lambda lm: lm.id):
            rec: dict[str, object] = {
                "id": lm.id,
                "x": float(lm.p_surveyed[0]),
                "y": float(lm.p_surveyed[1]),
                "z": float(lm.p_surveyed[2]),
                "radio": lm.address,
                "floor": lm.floor,
            }
            if lm.panel_size_m > 0:
                rec.update(passive=True, size_m=lm.panel_size_m)
            if lm.map_sigma_m is not None:
                rec["sigma_m"] = lm.map_sigma_m
            out.append(rec)
        return out
