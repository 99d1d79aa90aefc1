"""`AlertWatch`: reads the running site and says which alert conditions hold now
(`live.alerts.Condition`), for the `AlertBook`.

- `robot_lost`: a robot's localizer is in mode `lost` (an agent's: while it is connected).
- `robot_offline`: an agent (`irloc agent`) is disconnected (its connection went OFFLINE
  or broke).
- `camera_stale`: no frame (or spot set) reached a robot's localizer for `stale_s`; for an
  agent, no pose message (it sends one per frame, with or without a pose). Counted from the
  robot's start, so a camera that never delivers is stale too.
- `odometry_stale`: a robot that has had wheel odometry had none for `stale_s` (robots
  without wheels never raise it; agents' wheels are theirs to watch).
- `landmark_unreachable`: a landmark's radio stopped answering (the gateway's retries
  failed: dead batteries, a module taken down, out of range); not judged while the radio
  link itself is down.
- `landmark_low_battery`: a landmark's supply read at or below the gateway's low threshold
  (until it reads its hysteresis above it: new cells).
- `radio_down`: the gateway's serial link is not open.

Frames and odometry are seen through a tap on each robot's runner (`RobotRunner.add_tap`),
stamped with `clock` on the feeding thread; the rest is read at each check.
"""

from __future__ import annotations

import time
import weakref
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol

from live.agent_runner import AgentRunner
from live.alerts import Condition
from live.robots import RobotRunner
from localizer.events import Event, FrameObserved, OdometryMeasured, SpotsObserved
from rf_gateway.gateway import Gateway

RADIO = "radio"
"""The subject of `radio_down`."""


class GatewayHost(Protocol):
    """What the watch reads of the LED facade (`live.facades.LedsAndRadio`)."""

    gateway: Gateway | None


@dataclass
class _Seen:
    """When a robot's sensors last delivered (clock seconds)."""

    started: float
    frame: float | None = None
    odometry: float | None = None
    agent_count: tuple[int, int | None] = (-1, None)


class AlertWatch:
    """See the module. `runners()` lists the live robots (`Robots.runners`)."""

    def __init__(
        self,
        runners: Callable[[], Iterable[RobotRunner]],
        leds: GatewayHost,
        *,
        stale_s: float = 5.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.runners, self.leds = runners, leds
        self.stale_s = stale_s
        self.clock = clock
        self._seen: weakref.WeakKeyDictionary[RobotRunner, _Seen] = weakref.WeakKeyDictionary()

    def _tap(self, seen: _Seen) -> Callable[[Event], None]:
        def tap(event: Event) -> None:
            if isinstance(event, FrameObserved | SpotsObserved):
                seen.frame = self.clock()
            elif isinstance(event, OdometryMeasured):
                seen.odometry = self.clock()

        return tap

    def _seen_of(self, runner: RobotRunner, now: float) -> _Seen:
        seen = self._seen.get(runner)
        if seen is None:
            seen = self._seen[runner] = _Seen(started=now)
            if not isinstance(runner, AgentRunner):
                runner.add_tap(self._tap(seen))
        return seen

    def conditions(self) -> tuple[list[Condition], set[tuple[str, str | None]]]:
        """(the conditions holding now, the (kind, subject | None) that cannot be judged)."""
        now = self.clock()
        holding: list[Condition] = []
        unsure: set[tuple[str, str | None]] = set()
        for runner in self.runners():
            holding += self._robot(runner, now, unsure)
        holding += self._radio(unsure)
        return holding, unsure

    def _robot(
        self, runner: RobotRunner, now: float, unsure: set[tuple[str, str | None]]
    ) -> list[Condition]:
        name = runner.name
        seen = self._seen_of(runner, now)
        out: list[Condition] = []
        if isinstance(runner, AgentRunner):
            count = (runner.frames, runner.last_seq)
            if count != seen.agent_count:
                seen.agent_count, seen.frame = count, now
            if not runner.connected:
                out.append(
                    Condition(
                        "robot_offline",
                        name,
                        f"agent {name} is disconnected",
                        robot=name,
                        data={"source": "agent"},
                    )
                )
                unsure.update({("robot_lost", name), ("camera_stale", name)})
                return out
        if runner.mode == "lost":
            out.append(Condition("robot_lost", name, f"robot {name} is lost", robot=name))
        last_frame = seen.frame if seen.frame is not None else seen.started
        if now - last_frame >= self.stale_s:
            what = "no pose message" if isinstance(runner, AgentRunner) else "no camera frame"
            out.append(
                Condition(
                    "camera_stale",
                    name,
                    f"robot {name}: {what} for {now - last_frame:.0f} s",
                    robot=name,
                    data={"silent_s": round(now - last_frame, 1), "ever": seen.frame is not None},
                )
            )
        if seen.odometry is not None and now - seen.odometry >= self.stale_s:
            silent = round(now - seen.odometry, 1)
            out.append(
                Condition(
                    "odometry_stale",
                    name,
                    f"robot {name}: no wheel odometry for {silent:.0f} s",
                    robot=name,
                    data={"silent_s": silent},
                )
            )
        return out

    def _radio(self, unsure: set[tuple[str, str | None]]) -> list[Condition]:
        gw = self.leds.gateway
        if gw is None:
            return []
        state = str(gw.transport.state)
        if state != "open":
            unsure.add(("landmark_unreachable", None))
            return [Condition("radio_down", RADIO, f"radio link is {state}", data={"state": state})]
        out: list[Condition] = []
        addresses = gw.landmarks
        for lid in sorted(gw.unreachable):
            address = addresses.get(lid, "?")
            out.append(
                Condition(
                    "landmark_unreachable",
                    str(lid),
                    f"landmark {lid} does not answer (radio {address})",
                    landmark_id=lid,
                    data={"address": address},
                )
            )
        for lid in sorted(gw.batteries.low):
            reading = gw.batteries.latest(lid)
            mv = None if reading is None else reading.supply_mv
            days = None if reading is None else reading.days_left
            said = "" if mv is None else f": {mv} mV"
            out.append(
                Condition(
                    "landmark_low_battery",
                    str(lid),
                    f"landmark {lid} battery low{said}",
                    landmark_id=lid,
                    data={"supply_mv": mv, "days_left": days},
                )
            )
        return out
