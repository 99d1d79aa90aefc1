"""Noticing a robot on the wrong floor. On a site with several floors each robot carries a
`fleet.floor_fit.FloorFit`: as soon as its view stops fitting its floor's map its floor is
*unknown* and its poses are withheld (no pose on the old floor's map goes out). Such a
robot, and one that has had no fix on its floor's map for a while, is tried against the
other floors' maps, and the floor whose landmarks it identifies and tracks is *proposed*
(an event `floor_proposed`; the API accepts or rejects it). A robot is never switched
silently: until someone (or the fleet) accepts, it stays on the floor it was on (its
floor unknown while its view does not fit it).

A trial is a second localizer per other floor, fed the same events as the robot's own
(`RobotRunner.add_tap`) on a worker thread. Its LED requests go to the LED coordinator
under the name `<robot>@<floor>`, so it identifies that floor's landmarks by switching their
LEDs as any robot does. A trial ends when the robot fixes on its own floor again, when a
proposal is accepted or rejected, or after `trial_s` without one.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from fleet.floor_fit import FloorFit, FloorFitConfig
from live.events import EventHub
from live.floors import Near, SiteFloors
from live.led_filter import only_landmarks
from live.robots import LocalizerLike, RobotRunner, make_localizer
from localizer.config import LocalizerConfig
from localizer.events import (
    Event,
    FrameObserved,
    LedRequest,
    LedsChanged,
    PoseEstimate,
    RelocalizeRequested,
)
from localizer.spots import DetectionConfig, detect_spots
from store.errors import NotFoundError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FloorWatchConfig:
    """When to try other floors and when to propose one.

    Attributes:
        suspect_after_s: seconds (site clock) without a fix on its own floor since its
            last fix before its view is tried on the other floors (a robot that never had
            one is not tried: it identifies on the floor it starts on).
        fixes_to_propose: consecutive landmark fixes on another floor's map that make a
            proposal.
        trial_s: a trial that proposes nothing within this is dropped (wall seconds).
        retry_after_s: after a dropped trial or a rejected proposal, wait this long.
        own_fix_hold_s: a trial ends once the robot has held fixes on its own floor this
            long (wall seconds; a moment's fix on a ceiling that only looks like its own
            floor's, by the lift, does not end it).
        period_s: how often robots are checked (wall seconds).
        fit: when a robot's floor becomes unknown and known again (`FloorFit`).
    """

    suspect_after_s: float = 8.0
    fixes_to_propose: int = 5
    trial_s: float = 30.0
    retry_after_s: float = 10.0
    own_fix_hold_s: float = 3.0
    period_s: float = 0.5
    fit: FloorFitConfig = field(default_factory=FloorFitConfig)


@dataclass(frozen=True)
class FloorProposal:
    """A robot's view fits `floor`'s map: its pose there (metres, radians) at `t_ns`."""

    robot: str
    floor: str
    x: float
    y: float
    theta: float
    t_ns: int
    fixes: int


class _Trial:
    """One robot's view tried on one other floor's map."""

    def __init__(
        self,
        runner: RobotRunner,
        floor: str,
        localizer: LocalizerLike,
        ids: frozenset[int],
        request_leds: Callable[[str, LedRequest], None],
    ) -> None:
        self.runner, self.floor, self.localizer = runner, floor, localizer
        self._request_leds = request_leds
        self.started = time.monotonic()
        self.fixes = 0
        self.last: PoseEstimate | None = None
        self._ids = ids  # the landmarks of its floor's map
        self._queue: queue.SimpleQueue[Event | None] = queue.SimpleQueue()
        self._thread = threading.Thread(
            target=self._run, name=f"floor-trial-{runner.name}-{floor}", daemon=True
        )
        self._thread.start()
        runner.add_tap(self._queue.put)

    def stop(self) -> None:
        self.runner.remove_tap(self._queue.put)
        self._queue.put(None)

    def _run(self) -> None:
        name = f"{self.runner.name}@{self.floor}"
        while (event := self._queue.get()) is not None:
            if isinstance(event, LedsChanged):
                event = only_landmarks(event, self._ids)
            try:
                outputs = self.localizer.handle(event)
            except Exception:
                log.exception("floor trial %s failed", name)
                continue
            for out in outputs:
                if isinstance(out, LedRequest):
                    self._request_leds(name, out)
                elif isinstance(out, PoseEstimate):
                    self.fixes = self.fixes + 1 if out.mode == "landmark" else 0
                    self.last = out


class FloorWatch:
    """Try robots without a fix on the other floors; propose the floor that fits.

    Args:
        floors: the site's floors as the robots see them.
        events: the site's event hub (`floor_proposed`).
        request_leds: the LED coordinator's `request` (None: no radio, nothing is tried).
        clock_ns: the site clock.
        localizer_config: the trials' localizer tuning (the robots').
        config: when to try and propose.
    """

    def __init__(
        self,
        floors: SiteFloors,
        events: EventHub,
        request_leds: Callable[[str, LedRequest], None] | None,
        clock_ns: Callable[[], int],
        localizer_config: LocalizerConfig | None = None,
        config: FloorWatchConfig | None = None,
    ) -> None:
        self.floors, self.events, self.clock_ns = floors, events, clock_ns
        self._request_leds = request_leds
        self.localizer_config = localizer_config
        self.config = config or FloorWatchConfig()
        self._trials: dict[str, list[_Trial]] = {}
        self._proposals: dict[str, FloorProposal] = {}
        self._quiet_until: dict[str, float] = {}
        self._own_fix_since: dict[str, float] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._trial_from: dict[str, str] = {}  # robot -> the floor it was on when tried
        floors.add_listener(self._on_moved)

    # -- lifecycle -----------------------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="floor-watch", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self.floors.remove_listener(self._on_moved)
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        with self._lock:
            for name in list(self._trials):
                self._end(name)

    def _run(self) -> None:
        while not self._stop.wait(self.config.period_s):
            try:
                self.check()
            except Exception:
                log.exception("floor watch failed")

    # -- what others ask -----------------------------------------------------------------
    def trying(self, robot: str) -> bool:
        """Whether the robot's view is being tried on other floors now: its own LED
        requests wait meanwhile (two identifications would undo each other's probes)."""
        return robot in self._trials

    def proposal(self, robot: str) -> FloorProposal | None:
        """The floor proposed for `robot` now (with its latest pose there), or None."""
        with self._lock:
            found = self._proposals.get(robot)
            trial = next(
                (t for t in self._trials.get(robot, []) if found and t.floor == found.floor), None
            )
            if found is None or trial is None or trial.last is None:
                return found
            last = trial.last
            return FloorProposal(
                robot,
                found.floor,
                float(last.x),
                float(last.y),
                float(last.theta),
                last.t_ns,
                trial.fixes,
            )

    def accept(self, robot: str, *, by: str) -> FloorProposal:
        """Move the robot to its proposed floor, near its latest pose there.

        Raises:
            NotFoundError: no proposal for that robot (or an unknown robot).
        """
        found = self.proposal(robot)
        if found is None:
            raise NotFoundError(f"robot {robot!r} has no floor proposal")
        with self._lock:
            self._proposals.pop(robot, None)
            self._end(robot)
        self.floors.move(robot, found.floor, (found.x, found.y, found.theta), by=by)
        return found

    def reject(self, robot: str) -> FloorProposal:
        """Drop the robot's proposal (tried again after `retry_after_s`)."""
        with self._lock:
            found = self._proposals.pop(robot, None)
            if found is None:
                raise NotFoundError(f"robot {robot!r} has no floor proposal")
            self._end(robot)
            self._quiet_until[robot] = time.monotonic() + self.config.retry_after_s
        return found

    def _on_moved(self, robot: str, floor: str, old: str, near: Near | None) -> None:
        """A robot was told its floor (or a proposal accepted): its trials and proposal
        are moot (its own identification must not wait for them)."""
        with self._lock:
            self._proposals.pop(robot, None)
            self._end(robot)
            self._own_fix_since.pop(robot, None)

    # -- watching ------------------------------------------------------------------------
    def _fit(self, runner: RobotRunner, several: bool) -> FloorFit | None:
        """The robot's floor fit: one for each robot localized here on a site with
        several floors (with one floor there is no other to be on)."""
        if not several:
            runner.floor_fit = None
        elif runner.floor_fit is None:
            runner.floor_fit = FloorFit(self.config.fit)
        return runner.floor_fit

    def check(self) -> list[FloorProposal]:
        """One round: start, judge and end trials; returns the proposals made now."""
        made: list[FloorProposal] = []
        if self._request_leds is None:
            return made
        now_ns, now = self.clock_ns(), time.monotonic()
        cfg = self.config
        several = len(self.floors.floors.ids()) > 1
        with self._lock:
            for runner in self.floors.robots.runners():
                name = runner.name
                if runner.source == "agent":  # localized on board: not ours to try
                    continue
                fit = self._fit(runner, several)
                unknown = fit is not None and fit.unknown
                if name in self._trials and self._trial_from.get(name) != runner.floor:
                    self._end(name)  # moved meanwhile: those trials were of its old floor
                    self._proposals.pop(name, None)
                if runner.mode == "landmark" and not unknown:  # fixed on its own floor
                    since = self._own_fix_since.setdefault(name, now)
                    if name in self._trials and now - since >= cfg.own_fix_hold_s:
                        self._end(name)
                        self._proposals.pop(name, None)
                    if name not in self._trials:
                        continue
                else:
                    self._own_fix_since.pop(name, None)
                trials = self._trials.get(name)
                if trials is None:
                    # a robot that never had a fix identifies on the floor it starts on:
                    # trying others would stall its own identification (its probes wait)
                    fixed_ns = runner.last_fix_t_ns
                    without_s = 0.0 if fixed_ns is None else (now_ns - fixed_ns) * 1e-9
                    suspect = without_s >= cfg.suspect_after_s or (
                        unknown and self._sees_landmarks(runner)
                    )
                    if suspect and several and now >= self._quiet_until.get(name, 0):
                        self._start(runner)
                    continue
                if name not in self._proposals:
                    best = max(trials, key=lambda t: t.fixes)
                    if best.fixes >= cfg.fixes_to_propose and best.last is not None:
                        made.append(self._propose(runner, best))
                    elif now - best.started > cfg.trial_s:
                        self._end(name)
                        self._quiet_until[name] = now + cfg.retry_after_s
        return made

    def _start(self, runner: RobotRunner) -> None:
        others = [f for f in self.floors.floors.ids() if f != runner.floor]
        trials = []
        for floor in others:
            lmap, _ = self.floors.map_of(floor)
            if lmap.ids.size < 2:
                continue
            loc = make_localizer(runner.camera, lmap, runner.geometry, self.localizer_config)
            last = self._last_pose(runner)  # floors' frames are stacked: start near it
            if last is not None:
                t_ns, x, y, theta = last
                loc.handle(RelocalizeRequested(t_ns, (x, y, theta)))
            assert self._request_leds is not None
            ids = frozenset(int(i) for i in lmap.ids)
            trials.append(_Trial(runner, floor, loc, ids, self._request_leds))
        if trials:
            self._trials[runner.name] = trials
            self._trial_from[runner.name] = runner.floor
            log.info(
                "robot %s: no fix on floor %s, trying floors %s",
                runner.name,
                runner.floor,
                [t.floor for t in trials],
            )

    def _sees_landmarks(self, runner: RobotRunner) -> bool:
        """Whether the robot's latest frame shows two spots or more: a view that does not
        fit its floor is tried on the others once it shows a ceiling (not in the lift's
        cabin, where a trial's identification would only fail)."""
        frame = runner.recent[-1] if runner.recent else None
        if frame is None:
            return False
        if isinstance(frame, FrameObserved):
            cfg = self.localizer_config
            detection = cfg.detection if cfg is not None else DetectionConfig()
            return len(detect_spots(frame.image, detection).pixels) >= 2
        return len(frame.pixels) >= 2

    @staticmethod
    def _last_pose(runner: RobotRunner) -> tuple[int, float, float, float] | None:
        """(t_ns, x, y, theta) of the robot's latest pose on its floor's map, withheld or
        not; None when it has none."""
        fit = runner.floor_fit
        est = fit.last_estimate if fit is not None else None
        if est is not None:
            return est.t_ns, float(est.x), float(est.y), float(est.theta)
        upd = runner.latest
        if upd is None or upd.x is None or upd.y is None or upd.theta is None:
            return None
        return upd.t_ns, upd.x, upd.y, upd.theta

    def _propose(self, runner: RobotRunner, trial: _Trial) -> FloorProposal:
        assert trial.last is not None and trial.floor != runner.floor
        last = trial.last
        prop = FloorProposal(
            runner.name,
            trial.floor,
            float(last.x),
            float(last.y),
            float(last.theta),
            last.t_ns,
            trial.fixes,
        )
        self._proposals[runner.name] = prop
        self.events.emit(
            "floor_proposed",
            f"robot {runner.name} seems to be on floor {trial.floor}, not on floor "
            f"{runner.floor} where the site has it: its view fits floor {trial.floor}'s map "
            f"(at {prop.x:.2f}, {prop.y:.2f}); accept or reject",
            robot=runner.name,
            data={
                "floor": trial.floor,
                "from": runner.floor,
                "x": prop.x,
                "y": prop.y,
                "theta": prop.theta,
            },
        )
        return prop

    def _end(self, name: str) -> None:
        self._trial_from.pop(name, None)
        for trial in self._trials.pop(name, []):
            trial.stop()
