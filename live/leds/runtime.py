"""`LedScheduler`: runs the LED policy on the server's loop and keeps its books.

Every `period_s` it reads each robot's latest pose (speed and turn rate from the change since
the last plan) and plans (`policy.plan_leds`) on a worker thread (a plan for a hundred robots
would hold up every pose on the loop), then hands the lit set to the LED coordinator on the
loop, which lights it as the site's normal state (a robot's identification probe then darkens one
landmark *of it*). It also counts what the plan did: lit-seconds per landmark (the wear it
spreads, and each landmark's duty cycle for the days-left model), the site's lit fraction,
and why each landmark is lit.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
import threading
from collections.abc import Awaitable, Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from fleet.floor_fit import FloorFit
from lighting.floors import plan_leds_per_floor
from lighting.policy import LedPlan, RobotState, ScheduleConfig
from lighting.wake_window import WakeWindow
from live.poses import PoseUpdate
from localizer.camera import CameraModel
from localizer.events import LedsChanged, Mode
from localizer.geometry import wrap_angle
from store.models import DEFAULT_FLOOR

log = logging.getLogger(__name__)
_NS = 1e-9


class RunnerLike(Protocol):
    """What the scheduler reads of a `live.robots.RobotRunner`."""

    name: str
    camera: CameraModel
    latest: PoseUpdate | None

    @property
    def mode(self) -> Mode: ...


@dataclass
class _Motion:
    t_ns: int
    pose: tuple[float, float, float]
    v: float = 0.0
    omega: float = 0.0
    still_since_ns: int | None = None


class LedScheduler:
    """The scheduled LED policy, live.

    Args:
        landmarks: returns the controlled landmarks (IDs, positions shape (N, 3)).
        runners: returns the robots.
        max_speed: robot name -> maximum speed, m/s.
        lit_now: returns the confirmed LED state (None before the first).
        clock_ns: the site clock.
        config: the policy's tuning.
        period_s: time between plans, seconds.
        on_plan: called with each plan whose lit set differs from the previous one.
        set_awake: sets every landmark's time awake after a message (`ST`, seconds; the
            gateway's `set_awake_time`), for the wake window while robots identify (None:
            awake radios, no window).
        wake_window: when to raise and lower it.
        routes: robot name -> the points it drives to next (x, y), as its fleet manager
            knows them (the sim's routes, VDA 5050 order nodes); None or empty: unknown, its
            motion is extrapolated from its speed and turn rate.
    """

    def __init__(
        self,
        landmarks: Callable[[], tuple[list[int], npt.NDArray[np.float64]]],
        runners: Callable[[], Iterable[RunnerLike]],
        max_speed: Callable[[str], float],
        lit_now: Callable[[], LedsChanged | None],
        clock_ns: Callable[[], int],
        *,
        config: ScheduleConfig | None = None,
        period_s: float = 0.25,
        on_plan: Callable[[LedPlan], None] | None = None,
        set_awake: Callable[[float], Awaitable[object]] | None = None,
        wake_window: WakeWindow | None = None,
        routes: Callable[[str], tuple[tuple[float, float], ...]] | None = None,
        floors: Callable[[], Mapping[int, str]] | None = None,
    ) -> None:
        self.config = config or ScheduleConfig()
        self._floors = floors  # landmark ID -> floor (None: one floor)
        self.period_s = period_s
        self._landmarks = landmarks
        self._runners = runners
        self._max_speed = max_speed
        self._lit_now = lit_now
        self._clock_ns = clock_ns
        self.on_plan = on_plan
        self.plan: LedPlan | None = None
        self.lit_s: dict[int, float] = {}
        self.accounted_s = 0.0
        self.lit_landmark_s = 0.0
        self.plans = 0
        self._t_books_ns: int | None = None
        self._chosen_ns: dict[int, int] = {}
        self._motion: dict[str, _Motion] = {}
        self._pinned: dict[tuple[int, str], int] = {}  # (landmark, reason) -> until, ns
        self._awake_reasons: set[str] = set()  # pins that switch LEDs one at a time
        self._pins_lock = threading.Lock()  # pins come from the API's and services' threads
        self._task: asyncio.Task[None] | None = None
        self._set_awake = set_awake
        self.wake_window = wake_window if set_awake is not None else None
        self._awake_task: asyncio.Task[None] | None = None
        self._routes = routes

    # -- what others need ----------------------------------------------------------------
    def pin(
        self, landmark_ids: Iterable[int], reason: str, duration_s: float, *, awake: bool = False
    ) -> None:
        """Keep landmarks lit for `duration_s` (the survey, a staff member's check); the
        next plan lights them (`POST /leds/pin`). `awake`: whoever pinned them switches
        LEDs one at a time and waits for each (the survey's blinks, the wizard), so while
        such a pin runs the sleeping radios' wake window is open, as while a robot
        identifies."""
        until = self._clock_ns() + round(duration_s * 1e9)
        with self._pins_lock:
            for lid in landmark_ids:  # a landmark pinned for two reasons keeps both
                self._pinned[(int(lid), reason)] = until
            if awake:
                self._awake_reasons.add(reason)

    def unpin(self, landmark_id: int) -> bool:
        """End a landmark's pins (whatever their reason); False when it had none."""
        return self._unpin(lambda lid, _: lid == int(landmark_id)) > 0

    def unpin_reason(self, reason: str) -> int:
        """End every pin given for `reason` (the survey's, the wizard's when they end); how
        many there were."""
        return self._unpin(lambda _, why: why == reason)

    def _unpin(self, match: Callable[[int, str], bool]) -> int:
        with self._pins_lock:
            gone = [k for k in self._pinned if match(*k)]
            for k in gone:
                del self._pinned[k]
            self._awake_reasons &= {why for _, why in self._pinned}
        return len(gone)

    def pins(self) -> list[tuple[int, str, float]]:
        """(landmark ID, reason, seconds left) of every pin still running."""
        now = self._clock_ns()
        with self._pins_lock:
            pinned = sorted(self._pinned.items())
        return [
            (lid, reason, (until - now) * _NS) for (lid, reason), until in pinned if until > now
        ]

    def landmark_ids(self) -> list[int]:
        """The landmarks the schedule controls."""
        return list(self._landmarks()[0])

    # -- the books -----------------------------------------------------------------------
    def lit_ids(self) -> frozenset[int]:
        """What the plan lights (every landmark before the first plan)."""
        if self.plan is None:
            return frozenset(self._landmarks()[0])
        return self.plan.lit

    def reason(self, landmark_id: int) -> str | None:
        """Why a landmark is lit (None: dark by the plan)."""
        if self.plan is None:
            return "start"
        return self.plan.reasons.get(landmark_id)

    @property
    def lit_fraction(self) -> float:
        """Time-averaged share of the landmarks lit since the scheduler started."""
        n = len(self._landmarks()[0])
        return self.lit_landmark_s / (self.accounted_s * n) if self.accounted_s > 0 and n else 0.0

    def duty(self, landmark_id: int) -> float:
        """Share of the time this landmark was lit since the scheduler started."""
        return self.lit_s.get(landmark_id, 0.0) / self.accounted_s if self.accounted_s > 0 else 0.0

    def _heading(self) -> frozenset[int]:
        """What is lit once the commands in flight land: the confirmed state, with each
        landmark being switched counted as the last plan switched it (a plan must not
        spend its command budget again on a change already on its way, nor undo it)."""
        state = self._lit_now()
        ids = frozenset(self._landmarks()[0])
        if state is None:
            return ids
        confirmed = state.lit_among(ids) - state.changing
        moving = state.changing & ids
        if self.plan is None:
            return confirmed | moving
        return confirmed | (moving & self.plan.lit)

    def _confirmed(self) -> frozenset[int] | None:
        """The landmarks confirmed lit and not being switched (None before the first)."""
        state = self._lit_now()
        if state is None:
            return None
        ids = frozenset(self._landmarks()[0])
        return state.lit_among(ids) - state.changing

    def _account(self, t_ns: int) -> frozenset[int]:
        state = self._lit_now()
        ids = self._landmarks()[0]
        if state is None:  # before the gateway's start-up sweep (which lights every LED)
            return frozenset(ids)
        # Being switched counts as lit: a plan limited by the command budget must not drop
        # what the start-up sweep (or the previous plan) is lighting.
        lit = state.lit_among(ids) | (state.changing & frozenset(ids))
        if self._t_books_ns is not None:
            dt = max((t_ns - self._t_books_ns) * _NS, 0.0)
            self.accounted_s += dt
            self.lit_landmark_s += dt * len(lit)
            books = dict(self.lit_s)  # replaced whole: the API's threads read it meanwhile
            for lid in lit:
                books[lid] = books.get(lid, 0.0) + dt
            self.lit_s = books
        self._t_books_ns = t_ns
        return lit

    # -- planning ------------------------------------------------------------------------
    def _robots_on_floors(self, t_ns: int, floors: list[str]) -> tuple[list[RobotState], list[str]]:
        """Each robot's state and floor; a robot whose floor is unknown
        (`fleet.floor_fit`) is planned on every floor too, at its latest pose there (the
        floors' frames are stacked), so the ceiling of the floor it is really on is lit
        for it and for its trials."""
        robots: list[RobotState] = []
        robot_floors: list[str] = []
        for r in self._runners():
            state = self._robot_state(r, t_ns)
            floor = str(getattr(r, "floor", DEFAULT_FLOOR))
            robots.append(state)
            robot_floors.append(floor)
            fit = getattr(r, "floor_fit", None)
            if not isinstance(fit, FloorFit) or not fit.unknown:
                continue
            est = fit.last_estimate
            elsewhere = dataclasses.replace(state, mode="lost", pose=None)
            if est is not None:
                pose = (float(est.x), float(est.y), float(est.theta))
                age = max((t_ns - est.t_ns) * _NS, 0.0)
                cov = np.asarray(est.covariance, dtype=np.float64)
                elsewhere = dataclasses.replace(
                    state, mode="dead_reckoning", pose=pose, covariance=cov, pose_age_s=age
                )
            for other in floors:
                if other != floor:
                    robots.append(elsewhere)
                    robot_floors.append(other)
        return robots, robot_floors

    def _robot_state(self, runner: RunnerLike, t_ns: int) -> RobotState:
        upd = runner.latest
        vmax = self._max_speed(runner.name)
        if upd is None or upd.x is None or upd.y is None or upd.theta is None:
            return RobotState(runner.name, runner.camera, vmax, runner.mode, None)
        pose = (upd.x, upd.y, upd.theta)
        m = self._motion.get(runner.name)
        if m is None:
            m = self._motion[runner.name] = _Motion(upd.t_ns, pose, still_since_ns=upd.t_ns)
        elif upd.t_ns > m.t_ns:
            dt = (upd.t_ns - m.t_ns) * _NS
            dx, dy = pose[0] - m.pose[0], pose[1] - m.pose[1]
            heading = math.cos(pose[2]) * dx + math.sin(pose[2]) * dy
            m.v = heading / dt
            m.omega = float(wrap_angle(pose[2] - m.pose[2])) / dt
            if abs(m.v) >= self.config.parked_speed_mps or abs(m.omega) >= 0.05:
                m.still_since_ns = None
            elif m.still_since_ns is None:
                m.still_since_ns = m.t_ns
            m.t_ns, m.pose = upd.t_ns, pose
        still = 0.0 if m.still_since_ns is None else (t_ns - m.still_since_ns) * _NS
        route = () if self._routes is None else self._routes(runner.name)
        return RobotState(
            runner.name,
            runner.camera,
            vmax,
            runner.mode,
            pose,
            covariance=upd.covariance,
            pose_age_s=max((t_ns - upd.t_ns) * _NS, 0.0),
            v=m.v,
            omega=m.omega,
            still_s=still,
            route=route,
        )

    def step(self, t_ns: int) -> LedPlan:
        """Account the time since the last step and plan (call every `period_s`)."""
        return self._apply(t_ns, *self._plan(t_ns))

    def _plan(self, t_ns: int) -> tuple[LedPlan, list[RobotState], bool]:
        """The books and the plan (any one thread at a time: `_run` runs it off the loop,
        a plan for many robots takes long enough to hold up every pose on it)."""
        self._account(t_ns)
        lit = self._heading()
        ids, positions = self._landmarks()
        with self._pins_lock:
            self._pinned = {k: v for k, v in self._pinned.items() if v > t_ns}
            reasons: dict[int, list[str]] = {}
            for lid, reason in sorted(self._pinned):
                reasons.setdefault(lid, []).append(reason)
            pinned = {lid: ", ".join(rs) for lid, rs in reasons.items()}
            self._awake_reasons &= {reason for _, reason in self._pinned}
            switching = bool(self._awake_reasons)
        floor_of = {} if self._floors is None else self._floors()
        robots, robot_floors = self._robots_on_floors(t_ns, sorted(set(floor_of.values())))
        plan = plan_leds_per_floor(
            robots,
            robot_floors,
            ids,
            positions,
            [floor_of.get(i, DEFAULT_FLOOR) for i in ids],
            lit_now=lit,
            last_chosen_s={k: (t_ns - v) * _NS for k, v in self._chosen_ns.items()},
            wear_h={k: v / 3600.0 for k, v in self.lit_s.items()},
            pinned=pinned,
            config=self.config,
            confirmed=self._confirmed(),
        )
        for lid in plan.wanted | plan.planned:
            self._chosen_ns[lid] = t_ns
        return plan, robots, switching

    def _apply(
        self, t_ns: int, plan: LedPlan, robots: list[RobotState], switching: bool
    ) -> LedPlan:
        """Take a plan on the loop: the wake window, the coordinator (`on_plan`)."""
        self._update_wake_window(robots, t_ns, switching=switching)
        changed = self.plan is None or plan.lit != self.plan.lit
        self.plan = plan
        self.plans += 1
        if changed and self.on_plan is not None:
            self.on_plan(plan)
        return plan

    def _update_wake_window(
        self, robots: list[RobotState], t_ns: int, *, switching: bool = False
    ) -> None:
        """Open the window while a robot identifies or someone switching LEDs one at a time
        holds a pin (`pin(awake=True)`); close it `relax_after_s` after neither is so."""
        window = self.wake_window
        if window is None or self._set_awake is None:
            return
        identifying = switching or any(
            r.pose is None or r.mode in ("identifying", "lost") for r in robots
        )
        wake_s = window.update(t_ns * _NS, identifying=identifying)
        if wake_s is None:
            return
        previous, set_awake = self._awake_task, self._set_awake

        async def apply() -> None:
            if previous is not None:  # in order: the latest `ST` lands last
                with contextlib.suppress(Exception, asyncio.CancelledError):
                    await previous
            try:
                await set_awake(wake_s)
            except Exception:
                log.exception("setting the landmarks' time awake (ST) failed")

        self._awake_task = asyncio.get_running_loop().create_task(apply())

    # -- running -------------------------------------------------------------------------
    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run())

    async def stop(self) -> None:
        if self._awake_task is not None:
            self._awake_task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._awake_task
            self._awake_task = None
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    async def _run(self) -> None:
        while True:
            try:
                t_ns = self._clock_ns()
                self._apply(t_ns, *await asyncio.to_thread(self._plan, t_ns))
            except Exception:
                log.exception("LED schedule failed")
            await asyncio.sleep(self.period_s)
