"""`Commissioning`: the `commissioning` package's logic run on the live site (the facade the
REST routes under `/api/v1/commissioning/` and the viewer's panels both use).

One task on the server's loop takes every pose update from the pose bus and, on a worker
thread, feeds the doubt tracker (`commissioning.doubt`) and the identification wizard
(`commissioning.wizard`): every robot's estimate, and for the wizard's robot its frame's
spots (detected here, or as a remote robot sent them). Every LED state the gateway publishes
reaches the wizard too. What the wizard returns is carried out here: LED switches go to the
LED coordinator as the requests of "wizard" (one landmark against the lit set, as robots
identify), a new radio's LED through the radio, positions into the map with the user as the
actor. docs/commissioning.md.
"""

from __future__ import annotations

import concurrent.futures
import logging
import statistics
import threading
from collections.abc import Callable, Coroutine, Sequence
from typing import Any

import numpy as np

from commissioning.candidates import doubted_candidates, new_radio_candidates
from commissioning.coverage import (
    Coverage,
    CoverageConfig,
    SpacingFlag,
    coverage_grid,
    spacing_flags,
)
from commissioning.doubt import Doubt, DoubtConfig, DoubtTracker
from commissioning.types import Candidate, MapLandmark
from commissioning.wizard import (
    Cancel,
    Confirm,
    Finished,
    FrameSeen,
    IdentificationWizard,
    LedsSeen,
    PoseSeen,
    RadioSwitched,
    SaveLandmark,
    Skip,
    Start,
    SwitchAnyway,
    SwitchLandmark,
    SwitchRadio,
    WizardConfig,
    WizardEvent,
    WizardOutput,
    WizardStatus,
)
from live.facades import LedsAndRadio, Robots
from live.pose_pump import PosePump
from live.poses import PoseUpdate
from localizer.events import FrameObserved, LedRequest, LedsChanged
from localizer.spots import DetectionConfig, detect_spots
from rf_gateway.errors import RfGatewayError
from store import MapRepository
from store.errors import ConflictError, NotFoundError, UnavailableError
from store.models import LandmarkCreate, LandmarkPublic, LandmarkUpdate

log = logging.getLogger(__name__)
WIZARD = "wizard"
"""The LED coordinator's name for the wizard's requests."""

WIZARD_PIN_S = 60.0
"""Under an LED schedule the landmark the wizard switches is kept lit this long after each
switch (a pin of the schedule, "pinned: wizard"), or until the wizard finishes, seconds."""


class Commissioning:
    """Doubt detection and the identification wizard on the live site.

    Args:
        map, robots, leds: the site's facades.
        submit: runs a coroutine on the server's loop from any thread (`SiteServices.submit`).
        doubt, wizard, detection: tuning.
        batch_s: pose updates are taken in batches at most this often, seconds (one worker
            thread hop a batch, not one a pose).
    """

    def __init__(
        self,
        map: MapRepository,
        robots: Robots,
        leds: LedsAndRadio,
        submit: Callable[[Coroutine[Any, Any, Any]], concurrent.futures.Future[Any]],
        *,
        doubt: DoubtConfig | None = None,
        wizard: WizardConfig | None = None,
        detection: DetectionConfig | None = None,
        batch_s: float = 0.05,
    ) -> None:
        self.map, self.robots, self.leds, self._submit = map, robots, leds, submit
        self.detection = detection or DetectionConfig()
        self.batch_s = batch_s
        self._doubt = DoubtTracker(doubt)
        self._wizard = IdentificationWizard(wizard)
        self._lock = threading.RLock()
        self._actor = "wizard"
        self._pump = PosePump(robots, self._take, batch_s=batch_s, name="commissioning")
        self._listening = False

    # -- lifecycle ----------------------------------------------------------------------------
    def start(self) -> None:
        """Subscribe to the poses, the map and the LEDs (on the server's loop)."""
        self._on_map(self.map.list())
        self.map.add_listener(self._on_map)
        self._listening = self.leds.add_listener(self._on_leds)
        self._pump.start()

    async def stop(self) -> None:
        """Abandon a running identification (the site relights every LED when it stops)."""
        self.map.remove_listener(self._on_map)
        if self._listening:
            self.leds.remove_listener(self._on_leds)
        await self._pump.stop()

    @property
    def failures(self) -> int:
        """Pose batches that failed (logged)."""
        return self._pump.failures

    # -- inputs -------------------------------------------------------------------------------
    def _on_map(self, landmarks: list[LandmarkPublic]) -> None:
        with self._lock:
            self._doubt.set_map({lm.id: (lm.x, lm.y, lm.z) for lm in landmarks})

    def _on_leds(self, event: LedsChanged) -> None:
        controlled = self.leds.controlled
        self._feed(LedsSeen(event.t_ns, event.lit_among(controlled), frozenset(event.changing)))

    def _take(self, batch: Sequence[PoseUpdate]) -> None:
        """Pose updates: to the doubt tracker, and to the wizard (with the frame's spots for
        its robot)."""
        with self._lock:
            wizard_robot = self._wizard.status().robot if self._wizard.running else None
        for upd in batch:
            pose = upd.estimate()
            try:
                runner = self.robots.get(upd.robot)
            except KeyError:
                continue
            with self._lock:
                if pose is None:
                    self._doubt.unlocalized(upd.robot)
                    continue
                self._doubt.observe(upd.robot, runner.camera, pose)
            if upd.robot != wizard_robot:
                self._feed(PoseSeen(upd.robot, pose))
                continue
            frame = runner.frame_at(upd.t_ns)
            if frame is None:
                self._feed(PoseSeen(upd.robot, pose))
                continue
            if isinstance(frame, FrameObserved):
                pixels = detect_spots(frame.image, self.detection).pixels
            else:
                pixels = frame.pixels
            self._feed(FrameSeen(upd.robot, pose, np.asarray(pixels, dtype=np.float64)))

    def _feed(self, event: WizardEvent) -> list[WizardOutput]:
        with self._lock:
            if not self._wizard.running and not isinstance(event, Start):
                if isinstance(event, PoseSeen | FrameSeen):
                    self._wizard.handle(event)  # remembers the robots' fixes
                return []
            outputs = self._wizard.handle(event)
            for out in outputs:
                self._carry_out(out)
            return outputs

    # -- outputs ------------------------------------------------------------------------------
    def _carry_out(self, out: WizardOutput) -> None:
        if isinstance(out, SwitchLandmark):
            coordinator = self.leds.coordinator
            if coordinator is None:
                raise UnavailableError("no radio: the site runs without a gateway")
            # Under an LED schedule the landmark measured must be lit when it is "on": the
            # request darkens it among the schedule's lit set, which needs it in that set.
            self.leds.keep_lit([out.landmark_id], WIZARD, WIZARD_PIN_S, awake=True)
            dark = frozenset() if out.on else frozenset({out.landmark_id})
            req = LedRequest(all_lit=True, dark=dark)
            coordinator.request(WIZARD, req)
        elif isinstance(out, SwitchRadio):
            self._switch_radio(out.address, out.on)
        elif isinstance(out, SaveLandmark):
            self._save(out)
        elif isinstance(out, Finished):
            self.leds.release(WIZARD)
            log.info("identification %s: saved %s, skipped %s", out.phase, out.saved, out.skipped)

    def _switch_radio(self, address: str, on: bool) -> None:
        fut = self._submit(self.leds.radio_led(address, on))

        def done(f: concurrent.futures.Future[None]) -> None:
            exc = f.exception()
            t_ns = self.robots.clock_ns()
            error = "" if exc is None else str(exc) or type(exc).__name__
            self._feed(RadioSwitched(t_ns, address, on, error))

        fut.add_done_callback(done)

    def _save(self, out: SaveLandmark) -> None:
        x, y, z = out.position
        c = out.candidate
        if c.radio is None:
            self.map.update(c.landmark_id, LandmarkUpdate(x=x, y=y, z=z), actor=self._actor)
        else:
            data = LandmarkCreate(id=c.landmark_id, x=x, y=y, z=z, radio=c.radio)
            self.map.create(data, actor=self._actor)

    # -- doubt --------------------------------------------------------------------------------
    def doubted(self) -> dict[int, Doubt]:
        """The doubted landmarks, by ID."""
        with self._lock:
            return self._doubt.doubted()

    def doubt(self, landmark_id: int) -> Doubt:
        """A landmark's chances and uses so far."""
        with self._lock:
            return self._doubt.record(landmark_id)

    def to_identify(self, radios: Sequence[tuple[str, str]] = ()) -> list[Candidate]:
        """Doubted unlocked landmarks, then the radios (address, node identifier) that are
        not in the map (from `LedsAndRadio.discover`), each with the ID it would get."""
        lms = self.map.list()
        out = doubted_candidates(self.doubted(), {lm.id for lm in lms if lm.locked})
        known = {lm.radio for lm in lms if lm.radio}
        found = [(a, n) for a, n in radios if a not in known]
        return out + new_radio_candidates(found, {lm.id for lm in lms})

    # -- coverage -------------------------------------------------------------------------------
    def coverage(self, robot: str, *, step_m: float = 0.25) -> Coverage:
        """Landmarks in view and expected error over the floor, for `robot`'s camera and the
        current map (`commissioning.coverage`); ValueError for a grid too fine, NotFoundError
        for an unknown robot."""
        camera = self.robots.get(robot).camera
        lms = self.map.list()
        if not lms:
            raise ValueError("coverage: the map has no landmarks")
        pos = np.array([[lm.x, lm.y, lm.z] for lm in lms])
        return coverage_grid(camera, pos, CoverageConfig(step_m=step_m))

    def spacing(self) -> list[SpacingFlag]:
        """Landmark pairs spaced outside the recommended range for their ceiling height."""
        lms = self.map.list()
        ids = np.array([lm.id for lm in lms], dtype=np.int64)
        pos = np.array([[lm.x, lm.y, lm.z] for lm in lms]).reshape(-1, 3)
        return spacing_flags(ids, pos)

    # -- the wizard ---------------------------------------------------------------------------
    def status(self) -> WizardStatus:
        with self._lock:
            return self._wizard.status()

    def start_wizard(self, robot: str, queue: Sequence[Candidate], *, actor: str) -> WizardStatus:
        """Start identifying `queue` with `robot`'s camera. ConflictError when running,
        UnavailableError without a radio, ValueError for a bad queue or robot."""
        if self.leds.coordinator is None:
            raise UnavailableError("no radio: the site runs without a gateway")
        runners = {r.name: r for r in self.robots.runners()}
        lms = self.map.list()
        zs = [lm.z for lm in lms]
        with self._lock:
            if self._wizard.running:
                raise ConflictError("the identification wizard is already running")
            camera = runners[robot].camera if robot in runners else None
            if camera is None:
                raise NotFoundError(
                    f"unknown robot {robot!r}; robots: {', '.join(sorted(runners))}"
                )
            self._actor = actor
            event = Start(
                self.robots.clock_ns(),
                robot,
                camera,
                tuple(queue),
                {lm.id: MapLandmark(lm.id, lm.x, lm.y, lm.z, lm.locked) for lm in lms},
                float(statistics.median(zs)) if zs else 2.5,
                tuple(sorted(runners)),
            )
            self._feed(event)
            led = self.leds.gateway.leds if self.leds.gateway is not None else None
            if led is not None:
                self._on_leds(led)
            return self._wizard.status()

    def _act(self, make: Callable[[int], WizardEvent], actor: str) -> WizardStatus:
        with self._lock:
            if not self._wizard.running:
                raise ConflictError("the identification wizard is not running")
            self._actor = actor
            try:
                self._feed(make(self.robots.clock_ns()))
            except RfGatewayError as exc:
                raise UnavailableError(str(exc)) from exc
            return self._wizard.status()

    def confirm(
        self,
        *,
        actor: str,
        position: tuple[float, float, float] | None = None,
        accept_far: bool = False,
    ) -> WizardStatus:
        """Save the agreed measurement (or `position`), then go to the next candidate."""
        return self._act(lambda t: Confirm(t, position, accept_far), actor)

    def skip(self, *, actor: str) -> WizardStatus:
        return self._act(Skip, actor)

    def switch_anyway(self, *, actor: str) -> WizardStatus:
        return self._act(SwitchAnyway, actor)

    def cancel(self, *, actor: str) -> WizardStatus:
        return self._act(Cancel, actor)
