"""The one-at-a-time LED identification wizard (the logic; `web.panels.wizard` is its GUI).

It steps through candidates (`web.services.Candidate`): landmarks of the map (doubted, or
named by staff) and new radios from discovery. For each one it darkens the others and lights
that one alone, takes the chosen robot's next camera frame, finds the spot and, when the
robot is localized, computes the landmark's position on the ceiling: the spot's ray from the
camera, placed by the robot's own estimate for that frame, intersected with the LED's height
(`web.geometry.landmark_from_spot`). Staff confirm (a landmark is moved, a new radio becomes
a landmark with that position and its address; both through the site's data layer and audit
log), skip, retry or type the position by hand. Cancelling, or finishing, restores every LED
to its state before the start (radios from discovery are left lit, as landmarks are kept).

Methods are called from viser's callback threads: one lock serialises them. Waiting for the
radio and for a fresh frame happens in the caller's thread.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from web.measure import Measurement, describe, measure_landmark
from web.services import CameraView, Candidate, ViewerSite

Phase = Literal["idle", "measured", "done", "cancelled"]


@dataclass(frozen=True)
class WizardConfig:
    """Wizard settings.

    Attributes:
        frame_timeout_s: how long to wait for a frame taken after the LED change, seconds.
        fix_timeout_s: how long to wait for the robot to fix its pose from the other
            landmarks once they are lit again, seconds.
        fix_settle_s: ... and then for it to stay fixed this long, seconds.
        settle_s: a frame counts once taken this long after the radio confirmed the change.
        max_fix_age_s: the robot's last landmark fix must be this recent, seconds.
        poll_s: polling period while waiting for a frame, seconds.
        led_tries: how often to (re)send an LED state that something else overrode.
        led_check_s: wait this long after sending before checking the LED state, seconds.
        frames: positions from up to this many consecutive frames are combined (median).
    """

    frame_timeout_s: float = 3.0
    fix_timeout_s: float = 10.0
    fix_settle_s: float = 0.5
    settle_s: float = 0.05
    max_fix_age_s: float = 3.0
    poll_s: float = 0.03
    led_tries: int = 6
    led_check_s: float = 0.3
    frames: int = 5


@dataclass
class WizardState:
    """Where the wizard stands (a copy is handed to the GUI)."""

    phase: Phase = "idle"
    queue: list[Candidate] = field(default_factory=list)
    index: int = 0
    robot: str = ""
    measurement: Measurement | None = None
    saved: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)

    @property
    def candidate(self) -> Candidate | None:
        """What is lit alone now."""
        return self.queue[self.index] if self.phase == "measured" else None

    @property
    def current(self) -> int | None:
        """The landmark ID lit alone now (for a new radio: the ID it will get)."""
        c = self.candidate
        return None if c is None else c.landmark_id

    @property
    def progress(self) -> float:
        """Percent of the queue dealt with."""
        return 100.0 * self.index / len(self.queue) if self.queue else 0.0


class IdentificationWizard:
    """One wizard per site (the LEDs are shared)."""

    def __init__(self, site: ViewerSite, config: WizardConfig | None = None) -> None:
        self.site = site
        self.config = config or WizardConfig()
        self._lock = threading.RLock()
        self._state = WizardState()
        self._previous_lit: frozenset[int] | None = None
        self._radio_lit: str | None = None  # a new radio this wizard lit
        self._mute: frozenset[int] = frozenset()  # landmarks whose radio did not answer
        self._snapshot = WizardState()

    @property
    def state(self) -> WizardState:
        """A copy of the state as of the last finished step (never waits for a running one)."""
        return self._snapshot

    def _publish(self) -> None:
        s = self._state
        self._snapshot = WizardState(
            s.phase, list(s.queue), s.index, s.robot, s.measurement, list(s.saved),
            list(s.skipped),
        )  # fmt: skip

    @property
    def active(self) -> bool:
        return self.state.phase == "measured"

    def start(
        self, robot: str, candidates: Sequence[Candidate | int], *, actor: str
    ) -> Measurement:
        """Remember the LEDs, darken the new radios, then light the first candidate alone
        and measure it. Plain IDs are landmarks of the map.

        Raises:
            ValueError: when already running, the queue is empty, the robot is unknown, or a
                new radio does not answer (the LEDs are then restored).
        """
        with self._lock:
            if self._state.phase == "measured":
                raise ValueError("the identification wizard is already running")
            queue = [c if isinstance(c, Candidate) else Candidate(int(c)) for c in candidates]
            if not queue:
                raise ValueError("nothing to identify")
            if robot not in {r.name for r in self.site.robots()}:
                raise ValueError(f"unknown robot {robot!r}")
            self._previous_lit = self.site.lit()
            self._mute = frozenset()
            self.site.hold_leds(True)
            self._state = WizardState(phase="measured", queue=queue, robot=robot)
            try:
                for c in queue:  # unmapped LEDs would be stray spots in every frame
                    if c.radio is not None:
                        self.site.set_radio_led(c.radio, False, actor=actor)
                return self._measure(actor)
            except Exception:
                self._state.phase = "cancelled"
                self._restore(actor)
                raise
            finally:
                self._publish()

    def retry(self, *, actor: str) -> Measurement:
        """Measure the current landmark anew (the others are lit first so the robot re-fixes)."""
        with self._lock:
            self._need_running()
            try:
                return self._measure(actor)
            finally:
                self._publish()

    def confirm(self, *, actor: str, position: npt.ArrayLike | None = None) -> Measurement | None:
        """Save the measured position (or `position`, typed by hand), then go to the next.

        Returns:
            the next landmark's measurement, or None when the queue is finished.

        Raises:
            ValueError: when there is no position to save.
        """
        with self._lock:
            self._need_running()
            m = self._state.measurement
            p = None if position is None else np.asarray(position, dtype=np.float64).reshape(3)
            if p is None:
                if m is None or m.position is None:
                    raise ValueError("no measured position to save: retry or type it by hand")
                p = m.position
            c = self._state.queue[self._state.index]
            x, y, z = float(p[0]), float(p[1]), float(p[2])
            if c.radio is None:
                self.site.update_landmark(c.landmark_id, actor=actor, x=x, y=y, z=z)
            else:
                self.site.add_landmark(c.landmark_id, x, y, z, actor=actor, radio=c.radio)
                self._radio_lit = None  # a landmark now: the site switches it
            self._state.saved.append(c.landmark_id)
            try:
                return self._advance(actor)
            finally:
                self._publish()

    def skip(self, *, actor: str) -> Measurement | None:
        """Leave the current landmark as it is and go to the next."""
        with self._lock:
            self._need_running()
            self._state.skipped.append(self._state.queue[self._state.index].landmark_id)
            try:
                return self._advance(actor)
            finally:
                self._publish()

    def cancel(self, *, actor: str) -> None:
        """Stop and restore every LED to its state before `start`."""
        with self._lock:
            if self._state.phase != "measured":
                return
            self._state.phase = "cancelled"
            try:
                self._restore(actor)
            finally:
                self._publish()

    def abandon(self) -> None:
        """Stop without switching any LED (at shutdown the server relights them all);
        releases the hold on the robots' LED requests. Does not wait for a running step."""
        s = self._state
        if s.phase == "measured":
            s.phase = "cancelled"
            self._previous_lit = self._radio_lit = None
            self.site.hold_leds(False)
            self._publish()

    # -- internals -------------------------------------------------------------------------
    def _need_running(self) -> None:
        if self._state.phase != "measured":
            raise ValueError("the identification wizard is not running")

    def _advance(self, actor: str) -> Measurement | None:
        self._darken_radio(actor)
        self._state.index += 1
        self._state.measurement = None
        if self._state.index >= len(self._state.queue):
            self._state.phase = "done"
            self._restore(actor)
            return None
        return self._measure(actor)

    def _restore(self, actor: str) -> None:
        s = self._state
        try:
            if self._previous_lit is not None:
                self._set_leds(self._relight(), actor)
            for c in s.queue:
                if c.radio is not None and c.landmark_id not in s.saved:
                    self.site.set_radio_led(c.radio, True, actor=actor)
        finally:
            self._previous_lit = self._radio_lit = None
            self.site.hold_leds(False)

    def _darken_radio(self, actor: str) -> None:
        if self._radio_lit is not None:
            self.site.set_radio_led(self._radio_lit, False, actor=actor)
            self._radio_lit = None

    def _relight(self) -> frozenset[int]:
        """The LEDs to light for the robot to fix its pose (and at the end): those lit
        before the start and the new landmarks saved since."""
        s = self._state
        created = {c.landmark_id for c in s.queue if c.is_new} & set(s.saved)
        return (self._previous_lit or frozenset()) | created

    def _robot_pose(self, t_ns: int) -> tuple[tuple[float, float, float] | None, str]:
        """The robot's own estimate for its frame at `t_ns` (waits for the localizer)."""
        name = self._state.robot
        deadline = time.monotonic() + self.config.frame_timeout_s
        at = self.site.pose_at(name, t_ns)
        while at is None and time.monotonic() < deadline:
            time.sleep(self.config.poll_s)
            at = self.site.pose_at(name, t_ns)
        if at is None:
            return None, f"robot {name} has no pose for that frame"
        if at.last_fix_t_ns is None:
            return None, f"robot {name} has no landmark fix"
        age = (t_ns - at.last_fix_t_ns) * 1e-9
        if age > self.config.max_fix_age_s:
            return None, f"robot {name}'s last landmark fix is {age:.1f} s old"
        p = at.pose
        return (p.x, p.y, p.theta), ""

    def _wait_frame(self, after_ns: int) -> CameraView | None:
        deadline = time.monotonic() + self.config.frame_timeout_s
        while time.monotonic() < deadline:
            view = self.site.camera_view(self._state.robot)
            if view is not None and view.t_ns >= after_ns:
                return view
            time.sleep(self.config.poll_s)
        return None

    def _wait_fix(self, after_ns: int) -> None:
        """Wait for the robot to be in landmark mode `fix_settle_s` after its first fix
        since `after_ns` (a fix just re-acquired is rough)."""
        deadline = time.monotonic() + self.config.fix_timeout_s
        first: int | None = None
        while time.monotonic() < deadline:
            rb = next((r for r in self.site.robots() if r.name == self._state.robot), None)
            if rb is None:
                return
            fix = rb.last_fix_t_ns
            if fix is not None and fix >= after_ns:
                first = fix if first is None else first
                if rb.mode == "landmark" and fix - first >= self.config.fix_settle_s * 1e9:
                    return
            time.sleep(self.config.poll_s)

    def _now_ns(self) -> int:
        rb = next((r for r in self.site.robots() if r.name == self._state.robot), None)
        return 0 if rb is None else rb.now_ns

    def _measure(self, actor: str) -> Measurement:
        c = self._state.queue[self._state.index]
        lid = c.landmark_id
        landmarks = {lm.id: lm for lm in self.site.landmarks()}
        self._darken_radio(actor)
        relight = self._relight()
        if self._previous_lit is not None and not self._lit_is(relight):
            # light the others again so that the robot fixes its pose from them; its own
            # LED requests (to identify them again) may reach the radio meanwhile
            self.site.hold_leds(False)
            self._mute |= self.site.set_leds(relight, actor=actor)  # once: not to fight a
            # robot's sweep
            self._wait_fix(self._now_ns())
            self.site.hold_leds(True)
        alone = frozenset() if c.radio is not None else frozenset({lid})
        view = None
        for _ in range(self.config.led_tries):
            if not self._set_leds(alone, actor) or lid in self._mute:
                break
            if c.radio is not None and self._radio_lit is None:
                self.site.set_radio_led(c.radio, True, actor=actor)
                self._radio_lit = c.radio
            view = self._wait_frame(self._now_ns() + int(self.config.settle_s * 1e9))
            if self._lit_is(alone):  # still alone after the frame: the frame is good
                break
            view = None
        if lid in self._mute:
            why = f"landmark {lid} does not answer its radio (flat battery?): skip it"
            return self._keep(Measurement(lid, None, None, None, None, why))
        if view is None:
            why = f"could not keep landmark {lid} lit alone: retry"
            return self._keep(Measurement(lid, None, None, None, None, why))
        known = None if c.radio is not None else landmarks.get(lid)
        robot = self._state.robot
        pose, why = self._robot_pose(view.t_ns)  # its estimate for this very frame
        first = measure_landmark(self.site, robot, lid, known, view, pose, why)
        positions = [] if first.position is None else [first.position]
        while positions and len(positions) < self.config.frames:
            nxt = self._wait_frame(view.t_ns + 1)
            if nxt is None or not self._lit_is(alone):
                break
            view = nxt
            pose, why = self._robot_pose(view.t_ns)
            m = measure_landmark(self.site, robot, lid, known, view, pose, why)
            if m.position is None:
                break
            positions.append(m.position)
        if len(positions) < 2:
            return self._keep(first)
        p = np.median(np.array(positions), axis=0)
        text = describe(lid, p, known, f", median of {len(positions)} frames")
        return self._keep(Measurement(lid, first.view, first.spot, p, first.robot_pose, text))

    def _keep(self, m: Measurement) -> Measurement:
        self._state.measurement = m
        return m

    def _set_leds(self, lit: frozenset[int], actor: str) -> bool:
        """Send an LED state until it is the confirmed one (robots' requests queued before
        the hold may still override it once or twice)."""
        for _ in range(self.config.led_tries):
            self._mute |= self.site.set_leds(lit, actor=actor)
            time.sleep(self.config.led_check_s)
            if self._lit_is(lit):
                return True
        return False

    def _lit_is(self, lit: frozenset[int]) -> bool:
        """Whether the confirmed LEDs are `lit`, leaving out the landmarks whose radio does
        not answer (their LED state is unknown; a flat battery has darkened it)."""
        return self.site.lit() - self._mute == lit - self._mute
