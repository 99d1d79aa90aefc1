"""The live survey's blinks: one landmark dark at a time against the lit ceiling, chosen
among those the surveying robot sees that the survey still needs, never one another robot
cannot spare (one of the few its fix stands on).

Under an LED schedule the whole ceiling is kept lit while the survey drives (pins of the
schedule, "pinned: survey"): a dark landmark is not seen, and a blink darkens one landmark of
the schedule's lit set. The requests go to the LED coordinator as the requester "survey"
(`SURVEY`); each dark and each lit window starts once the radio confirmed the switch, so that
windows never run into each other and the recording names one dark landmark at a time
(`survey.blinks.BlinkConfig` timing).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

from localizer.events import LedRequest
from survey.blinks import BlinkConfig

if TYPE_CHECKING:  # the facades are handed in (live.services); typing only
    from live.facades import LedsAndRadio, Robots
    from live.leds.coordinator import LedCoordinator

log = logging.getLogger(__name__)

SURVEY = "survey"
"""The LED coordinator's name for the survey's requests (and the reason of its pins)."""

PIN_RENEW_S = 2.0
"""How often the survey renews its pins of the whole ceiling under an LED schedule, seconds."""

PIN_S = 10.0
"""How long each of those pins lasts, seconds (longer than a blink's dark and lit windows
with their confirmations; a survey that stopped without releasing them loses them then)."""


def blink_choice(
    candidates: Iterable[int],
    expected: Sequence[int] | None,
    spared: set[int],
    blinked: dict[int, int],
    first: set[int] | frozenset[int] = frozenset(),
    seen: Sequence[int] = (),
) -> int | None:
    """The landmark to darken next, or None (blink nothing now).

    Of the `candidates` (not yet identified, or not converged) that the surveying robot
    expects in view (`expected`; None while it has no pose: any candidate), those not
    `spared` (`needed_by_others`: darkening one would leave another robot's fix too few
    landmarks): first those its latest fix used (`seen`: surely in the image and detected;
    one merely expected may sit at the image's edge, where its spot is too faint to see, and
    its blink is wasted), among them the anchors not identified yet (nothing can be
    estimated before), then the one blinked least so far (ties: lowest ID)."""
    pending = set(candidates) - spared
    near = sorted(pending if expected is None else pending & set(expected))
    if not near:
        return None
    used = set(seen)
    return min(near, key=lambda i: (i not in used, i not in first, blinked.get(i, 0), i))


def needed_by_others(fixes: Iterable[Sequence[int]], keep: int) -> set[int]:
    """The landmarks other robots cannot spare, from the landmarks each of their latest
    fixes used (`fixes`): those of every fix of fewer than `keep` + 1 landmarks (darkening
    one would leave it fewer than `keep`). A robot that fixes from more may lose one for a
    dark window: its localizer hears of the switch before it happens and leaves it out, as
    when robots identify themselves. (Sparing every landmark any robot tracks, as before,
    let a robot parked under an anchor keep that anchor from ever being identified.)"""
    out: set[int] = set()
    for used in fixes:
        if len(used) <= keep:
            out.update(used)
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
        others_keep: int = 3,
        frames_in_state: Callable[[int, bool], int] | None = None,
        max_hold_s: float = 2.0,
    ) -> None:
        self.leds, self.robots, self.robot, self.ids = leds, robots, robot, list(ids)
        self.anchors = frozenset(anchors)
        self.settled, self.config, self.on_blink = settled, config, on_blink
        self.blinked = dict.fromkeys(self.ids, 0)
        self.others_keep = others_keep
        self.frames_in_state, self.max_hold_s = frames_in_state, max_hold_s

    def next_landmark(self) -> int | None:
        """What to darken now (`blink_choice` on the robots' latest poses)."""
        pose = self.robots.latest(self.robot)
        expected = None if pose is None or pose.x is None else pose.expected_ids
        seen = () if pose is None else pose.landmark_ids
        done = self.settled()
        return blink_choice(
            (i for i in self.ids if i not in done),
            expected,
            needed_by_others(self._other_fixes(), self.others_keep),
            self.blinked,
            self.anchors - done,
            seen,
        )

    def _other_fixes(self) -> list[tuple[int, ...]]:
        """The landmarks each other robot's latest fix used."""
        poses = (self.robots.latest(n) for n in self.robots.names() if n != self.robot)
        return [p.landmark_ids for p in poses if p is not None]

    def run(self, stop: threading.Event) -> None:
        coordinator = self.leds.coordinator
        if coordinator is None:
            return
        cfg = self.config
        dark_s = cfg.dark_frames * cfg.frame_period_s + cfg.radio_latency_s
        lit_s = cfg.lit_frames * cfg.frame_period_s + cfg.radio_latency_s
        try:
            self._blink(coordinator, stop, dark_s, lit_s)
        finally:
            coordinator.request(SURVEY, LedRequest(all_lit=True))
            self.leds.release(SURVEY)

    def _keep_ceiling_lit(self, renewed: float | None) -> float:
        """Under an LED schedule, keep every landmark lit while the survey drives (a dark
        one is neither seen nor named), renewed every `PIN_RENEW_S`; when it was renewed."""
        now = time.monotonic()
        if renewed is not None and now - renewed < PIN_RENEW_S:
            return renewed
        self.leds.keep_lit(self.ids, SURVEY, PIN_S, awake=True)
        return now

    def _blink(
        self, coordinator: LedCoordinator, stop: threading.Event, dark_s: float, lit_s: float
    ) -> None:
        cfg = self.config
        renewed = self._keep_ceiling_lit(None)
        if self.leds.scheduler is not None and not self._ceiling_lit(stop):
            return
        while not stop.is_set() and self.ids:
            renewed = self._keep_ceiling_lit(renewed)
            lid = self.next_landmark()
            if lid is None:  # nothing the survey needs in view: a window stays lit
                if stop.wait(dark_s + lit_s):
                    break
                continue
            self.blinked[lid] += 1
            coordinator.request(SURVEY, LedRequest(all_lit=True, dark=frozenset({lid})))
            self.on_blink()
            if not self._confirmed(lid, stop, lit=False) or not self._hold(
                lid, stop, lit=False, frames=cfg.dark_frames, min_s=dark_s
            ):
                break
            coordinator.request(SURVEY, LedRequest(all_lit=True))
            if not self._confirmed(lid, stop, lit=True) or not self._hold(
                lid, stop, lit=True, frames=cfg.lit_frames, min_s=lit_s
            ):
                break

    def _ceiling_lit(self, stop: threading.Event, timeout_s: float = 10.0) -> bool:
        """Wait until every landmark the radio controls is confirmed lit (the pins in force:
        a blink against a ceiling the schedule still darkens in places would name nothing),
        or `timeout_s` passed. False when stopped."""
        t0 = time.monotonic()
        unlit: set[int] = set()

        def all_lit(lit: frozenset[int], landmarks: frozenset[int]) -> bool:
            unlit.clear()
            unlit.update(landmarks - self.leds.unreachable - lit)  # a dead one never lights
            return not unlit

        met = self._wait_settled(all_lit, stop, timeout_s, poll_s=0.02)
        if met:
            log.info("survey: the ceiling is lit after %.1f s", time.monotonic() - t0)
        elif met is None:
            log.warning(
                "survey: landmarks %s not lit after %.0f s; blinking", sorted(unlit), timeout_s
            )
        return met is not False

    def _hold(
        self, landmark_id: int, stop: threading.Event, *, lit: bool, frames: int, min_s: float
    ) -> bool:
        """Keep the state in force `min_s`, then until the robot took `frames` frames in it
        (`frames_in_state`), at most `max_hold_s` in all. False when stopped."""
        if stop.wait(min_s):
            return False
        count = self.frames_in_state
        if count is None:
            return True
        deadline = time.monotonic() + max(self.max_hold_s - min_s, 0.0)
        while count(landmark_id, lit) < frames and time.monotonic() < deadline:
            if stop.wait(0.25 * self.config.frame_period_s):
                return False
        return True

    def _confirmed(
        self, landmark_id: int, stop: threading.Event, *, lit: bool, timeout_s: float = 1.0
    ) -> bool:
        """Wait until the gateway confirmed `landmark_id` lit (or dark), or `timeout_s`
        passed (a lost command, other requesters first). False when stopped."""
        met = self._wait_settled(
            lambda on, _: (landmark_id in on) == lit, stop, timeout_s, poll_s=0.005
        )
        return met is not False

    def _wait_settled(
        self,
        until: Callable[[frozenset[int], frozenset[int]], bool],
        stop: threading.Event,
        timeout_s: float,
        *,
        poll_s: float,
    ) -> bool | None:
        """Poll the gateway's LED state, settled (nothing being switched), until
        `until(lit, landmarks)` holds: True then, False when stopped, None after
        `timeout_s`."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            gateway = self.leds.gateway
            state = None if gateway is None else gateway.leds
            if gateway is not None and state is not None and not state.changing:
                landmarks = frozenset(gateway.landmarks)
                if until(state.lit_among(landmarks), landmarks):
                    return True
            if stop.wait(poll_s):
                return False
        return False if stop.is_set() else None
