"""The survey's LED program: every landmark stays lit (the robots keep their fixes) and one
at a time goes dark for a few frames, so the spot that vanishes names itself.

This is how robots already identify themselves against the lit ceiling (docs/localizer.md):
darkening one landmark costs a tracking robot at most that landmark for a few frames, never
its fix. A dark window of `dark_frames` camera frames is long enough for the spot tracker to
see the gap (`survey.observations`) and short enough to be ignored by the others.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from localizer.events import LedsChanged

NS = 1_000_000_000


@dataclass(frozen=True)
class BlinkConfig:
    """Timing of the blinks.

    Attributes:
        frame_period_s: the surveying camera's frame period, seconds.
        dark_frames: frames each landmark stays dark.
        lit_frames: frames with every landmark lit between two dark windows.
        radio_latency_s: margin for the radio's delivery, added to each window, seconds.
    """

    frame_period_s: float = 1.0 / 30.0
    dark_frames: int = 3
    lit_frames: int = 2
    radio_latency_s: float = 0.03

    def __post_init__(self) -> None:
        if not self.frame_period_s > 0:
            raise ValueError(f"BlinkConfig: frame_period_s must be > 0, got {self.frame_period_s}")
        if self.dark_frames < 2 or self.lit_frames < 1:
            raise ValueError("BlinkConfig: dark_frames must be >= 2 and lit_frames >= 1")

    @property
    def slot_s(self) -> float:
        """One landmark's dark window plus the lit gap after it, seconds."""
        frames = self.dark_frames + self.lit_frames
        return frames * self.frame_period_s + 2.0 * self.radio_latency_s


def blink_schedule(
    landmark_ids: Sequence[int], t_start_ns: int, t_end_ns: int, config: BlinkConfig
) -> list[LedsChanged]:
    """Round-robin dark windows over `landmark_ids` from `t_start_ns` to `t_end_ns`.

    Returns:
        LED changes in time order: for each slot "every landmark but one lit", then "all lit";
        the last change is "all lit".
    """
    return blink_schedule_in_view(
        landmark_ids, t_start_ns, t_end_ns, config, lambda _t: (), sweep_every=1
    )


def next_blink(
    in_view: Sequence[int], blinked: dict[int, int], slot: int, sweep_every: int
) -> int | None:
    """The landmark to darken in slot number `slot`, or None for the next of all in turn.

    Of the landmarks expected well inside the image (`in_view`: a spot vanishing there names
    itself; at the edge of a wide lens it fades by itself and names nothing), the one
    blinked least so far (`blinked`: windows so far by landmark); every `sweep_every`-th
    slot, or with none in view, None: a landmark with no position, or a rough one that is
    wrong, is never expected in view but must be named too.
    """
    near = [i for i in in_view if i in blinked]
    if not near or slot % sweep_every == 0:
        return None
    return min(near, key=lambda i: (blinked[i], near.index(i)))


def blink_schedule_in_view(
    landmark_ids: Sequence[int],
    t_start_ns: int,
    t_end_ns: int,
    config: BlinkConfig,
    in_view: Callable[[int], Sequence[int]],
    *,
    sweep_every: int = 3,
) -> list[LedsChanged]:
    """Dark windows aimed at what the robot sees (`next_blink`): `in_view(t_ns)` gives the
    landmarks expected well inside the image at that time (from the planned route, or the
    robot's pose, and the positions map.json has). The sweep slots go in turn to the
    landmarks never expected in view so far (those without a position), then to all. A
    round robin (`blink_schedule`) leaves a landmark to the luck of its window falling while
    the robot is under it: on a 50-landmark floor one landmark in 50 still had no name after
    two minutes.

    Returns:
        LED changes in time order, as `blink_schedule`.
    """
    ids = [int(i) for i in landmark_ids]
    if len(set(ids)) != len(ids):
        raise ValueError("blink schedule: landmark ids must be unique")
    if sweep_every < 1:
        raise ValueError(f"blink_schedule_in_view: sweep_every must be >= 1, got {sweep_every}")
    if not ids or t_end_ns <= t_start_ns:
        return [LedsChanged(t_start_ns, all_lit=True)]
    everyone = frozenset(ids)
    dark_ns = round((config.dark_frames * config.frame_period_s + config.radio_latency_s) * NS)
    slot_ns = round(config.slot_s * NS)
    blinked = dict.fromkeys(ids, 0)
    changes: list[LedsChanged] = []
    ever: set[int] = set()  # landmarks expected in view at some slot so far
    t, k, turn = t_start_ns, 0, 0
    while t + slot_ns <= t_end_ns:
        view = in_view(t + dark_ns // 2)
        ever.update(view)
        lid = next_blink(view, blinked, k, sweep_every)
        if lid is None:  # the sweep: first what was never expected in view (no position)
            pool = [i for i in ids if i not in ever] or ids
            lid, turn = pool[turn % len(pool)], turn + 1
        blinked[lid] += 1
        changes.append(LedsChanged(t, everyone - {lid}))
        changes.append(LedsChanged(t + dark_ns, all_lit=True))
        t += slot_ns
        k += 1
    if not changes:
        changes.append(LedsChanged(t_start_ns, all_lit=True))
    return changes
