"""The survey's LED program: every landmark stays lit (the robots keep their fixes) and one
at a time goes dark for a few frames, so the spot that vanishes names itself.

This is how robots already identify themselves against the lit ceiling (docs/localizer.md):
darkening one landmark costs a tracking robot at most that landmark for a few frames, never
its fix. A dark window of `dark_frames` camera frames is long enough for the spot tracker to
see the gap (`survey.observations`) and short enough to be ignored by the others.
"""

from __future__ import annotations

from collections.abc import Sequence
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
    ids = [int(i) for i in landmark_ids]
    if len(set(ids)) != len(ids):
        raise ValueError("blink_schedule: landmark ids must be unique")
    if not ids or t_end_ns <= t_start_ns:
        return [LedsChanged(t_start_ns, all_lit=True)]
    everyone = frozenset(ids)
    dark_ns = round((config.dark_frames * config.frame_period_s + config.radio_latency_s) * NS)
    slot_ns = round(config.slot_s * NS)
    changes: list[LedsChanged] = []
    t, k = t_start_ns, 0
    while t + slot_ns <= t_end_ns:
        lid = ids[k % len(ids)]
        changes.append(LedsChanged(t, everyone - {lid}))
        changes.append(LedsChanged(t + dark_ns, all_lit=True))
        t += slot_ns
        k += 1
    if not changes:
        changes.append(LedsChanged(t_start_ns, all_lit=True))
    return changes
