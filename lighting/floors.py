"""The LED schedule of a building with floors: each floor is planned on its own.

One radio network spans the floors, but a robot sees only its own floor's ceiling: an LED
switched on floor 1 is no landmark of floor 0. So the planner (`lighting.policy.plan_leds`)
runs once per floor, with the robots on that floor and that floor's landmarks, and the
plans are joined. The radio's command budget (`ScheduleConfig.max_switches`) applies to
each floor's plan.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from lighting.policy import LedPlan, RobotState, ScheduleConfig, plan_leds
from localizer.types import FloatArray


def plan_leds_per_floor(
    robots: Sequence[RobotState],
    robot_floors: Sequence[str],
    landmark_ids: Sequence[int],
    positions: FloatArray,
    landmark_floors: Sequence[str],
    *,
    lit_now: frozenset[int],
    last_chosen_s: Mapping[int, float],
    wear_h: Mapping[int, float],
    pinned: Mapping[int, str] | None = None,
    config: ScheduleConfig | None = None,
    confirmed: frozenset[int] | None = None,
) -> LedPlan:
    """`plan_leds` for each floor, joined.

    Args:
        robots: every robot's state; robot_floors: the floor of each (same order).
        landmark_ids: the controlled landmarks; positions: theirs, shape (N, 3), each in
            its floor's map frame; landmark_floors: the floor of each (same order).
        lit_now, last_chosen_s, wear_h, pinned, config, confirmed: as `plan_leds`.
    """
    if len(robots) != len(robot_floors) or len(landmark_ids) != len(landmark_floors):
        raise ValueError(
            f"plan per floor: {len(robots)} robots with {len(robot_floors)} floors, "
            f"{len(landmark_ids)} landmarks with {len(landmark_floors)} floors"
        )
    floors = sorted(set(landmark_floors))
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(floors) <= 1:
        return plan_leds(
            robots,
            landmark_ids,
            P,
            lit_now=lit_now,
            last_chosen_s=last_chosen_s,
            wear_h=wear_h,
            pinned=pinned,
            config=config,
            confirmed=confirmed,
        )
    plans = []
    for floor in floors:
        rows = [i for i, f in enumerate(landmark_floors) if f == floor]
        ids = [int(landmark_ids[i]) for i in rows]
        mine = frozenset(ids)
        plans.append(
            plan_leds(
                [r for r, f in zip(robots, robot_floors, strict=True) if f == floor],
                ids,
                P[rows],
                lit_now=lit_now & mine,
                last_chosen_s={k: v for k, v in last_chosen_s.items() if k in mine},
                wear_h={k: v for k, v in wear_h.items() if k in mine},
                pinned={k: v for k, v in (pinned or {}).items() if k in mine},
                config=config,
                confirmed=None if confirmed is None else confirmed & mine,
            )
        )
    return LedPlan(
        frozenset().union(*(p.lit for p in plans)),
        {k: v for p in plans for k, v in p.reasons.items()},
        frozenset().union(*(p.wanted for p in plans)),
        sum(p.deferred for p in plans),
        frozenset().union(*(p.planned for p in plans)),
    )
