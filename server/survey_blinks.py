"""The live survey's blinks: one landmark dark at a time against the lit ceiling, chosen
among those the surveying robot sees that the survey still needs, never one another robot is
tracking.

The requests go to the LED coordinator as the requester "survey" (`SURVEY`); each dark and
each lit window starts once the radio confirmed the switch, so that windows never run into
each other and the recording names one dark landmark at a time (`survey.blinks.BlinkConfig`
timing).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

from localizer.events import LedRequest
from survey.blinks import BlinkConfig

if TYPE_CHECKING:  # the facades are handed in (server.services); typing only
    from server.facades import LedsAndRadio, Robots

SURVEY = "survey"
"""The LED coordinator's name for the survey's requests."""


def blink_choice(
    candidates: Iterable[int],
    expected: Sequence[int] | None,
    tracked_by_others: set[int],
    blinked: dict[int, int],
    first: set[int] | frozenset[int] = frozenset(),
) -> int | None:
    """The landmark to darken next, or None (blink nothing now).

    Of the `candidates` (not yet identified, or not converged) that the surveying robot
    expects in view (`expected`; None while it has no pose: any candidate), those no other
    robot tracks (`tracked_by_others`: darkening them would cost that robot a landmark of
    its fix), the one blinked least so far (ties: lowest ID); those in `first` (the anchors
    not identified yet: nothing can be estimated before) before any other."""
    pending = set(candidates) - tracked_by_others
    near = sorted(pending if expected is None else pending & set(expected))
    if not near:
        return None
    return min(near, key=lambda i: (i not in first, blinked.get(i, 0), i))


def tracked_by_others(robots: Robots, robot: str) -> set[int]:
    """The landmarks every robot but `robot` tracks: those its latest fix used. (A landmark
    another robot merely expects in view may go dark: its localizer hears of the switch
    before it happens and leaves it out, as when robots identify themselves.)"""
    out: set[int] = set()
    for name in robots.names():
        pose = None if name == robot else robots.latest(name)
        if pose is not None:
            out.update(pose.landmark_ids)
    return out


class BlinkDriver:
    """Blink for the surveying robot until `stop` is set (`run`, in a thread of its own).

    Args:
        leds: the site's LEDs (its coordinator and gateway).
        robots: the live robots (poses: what each expects in view).
        robot: the surveying robot.
        ids: every landmark of the map.
        settled: returns the landmarks that need no more blinks (identified and converged).
        anchors: blinked first until identified.
        config: timing.
        on_blink: called once per dark window requested.
    """

    def __init__(
        self,
        leds: LedsAndRadio,
        robots: Robots,
        robot: str,
        ids: Sequence[int],
        settled: Callable[[], set[int]],
        config: BlinkConfig,
        on_blink: Callable[[], None],
        anchors: Sequence[int] = (),
    ) -> None:
        self.leds, self.robots, self.robot, self.ids = leds, robots, robot, list(ids)
        self.anchors = frozenset(anchors)
        self.settled, self.config, self.on_blink = settled, config, on_blink
        self.blinked = dict.fromkeys(self.ids, 0)

    def next_landmark(self) -> int | None:
        """What to darken now (`blink_choice` on the robots' latest poses)."""
        pose = self.robots.latest(self.robot)
        expected = None if pose is None or pose.x is None else pose.expected_ids
        done = self.settled()
        return blink_choice(
            (i for i in self.ids if i not in done), expected,
            tracked_by_others(self.robots, self.robot), self.blinked, self.anchors - done,
        )  # fmt: skip

    def run(self, stop: threading.Event) -> None:
        coordinator = self.leds.coordinator
        if coordinator is None:
            return
        cfg = self.config
        dark_s = cfg.dark_frames * cfg.frame_period_s + cfg.radio_latency_s
        lit_s = cfg.lit_frames * cfg.frame_period_s + cfg.radio_latency_s
        while not stop.is_set() and self.ids:
            lid = self.next_landmark()
            if lid is None:  # nothing the survey needs in view: a window stays lit
                if stop.wait(dark_s + lit_s):
                    break
                continue
            self.blinked[lid] += 1
            coordinator.request(SURVEY, LedRequest(all_lit=True, dark=frozenset({lid})))
            self.on_blink()
            if not self._confirmed(lid, stop, lit=False) or stop.wait(dark_s):
                break
            coordinator.request(SURVEY, LedRequest(all_lit=True))
            if not self._confirmed(lid, stop, lit=True) or stop.wait(lit_s):
                break
        coordinator.request(SURVEY, LedRequest(all_lit=True))

    def _confirmed(
        self, landmark_id: int, stop: threading.Event, *, lit: bool, timeout_s: float = 1.0
    ) -> bool:
        """Wait until the gateway confirmed `landmark_id` lit (or dark), or `timeout_s`
        passed (a lost command, other requesters first). False when stopped."""
        gateway = self.leds.gateway
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            state = None if gateway is None else gateway.leds
            ready = state is not None and gateway is not None and not state.changing
            if ready and (landmark_id in state.lit_among(gateway.landmarks)) == lit:  # type: ignore[union-attr]
                return True
            if stop.wait(0.005):
                return False
        return not stop.is_set()
