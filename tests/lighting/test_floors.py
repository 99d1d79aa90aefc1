"""The LED schedule per floor (lighting/floors.py): an LED of one floor is no landmark of
another, even where the floors' maps overlap."""

from __future__ import annotations

import numpy as np
import pytest

from lighting.floors import plan_leds_per_floor
from lighting.policy import plan_leds
from tests.lighting.test_policy import grid, robot

EMPTY: dict[int, float] = {}


def two_stacked_floors() -> tuple[list[int], np.ndarray, list[str]]:
    """Two 6 x 4 grids at the same (x, y): floor 0's IDs 100..., floor 1's 200..."""
    ids0, pos = grid(6, 4, 1.2)
    ids1 = [i + 100 for i in ids0]
    return ids0 + ids1, np.vstack([pos, pos]), ["0"] * len(ids0) + ["1"] * len(ids1)


def test_a_robot_on_floor_0_gets_only_floor_0_lit_where_the_floors_overlap() -> None:
    ids, pos, floors = two_stacked_floors()
    r = robot("r1", (2.4, 1.8, 0.0))
    plan = plan_leds_per_floor(
        [r], ["0"], ids, pos, floors, lit_now=frozenset(), last_chosen_s=EMPTY, wear_h=EMPTY
    )
    assert plan.lit and all(i < 200 for i in plan.lit)
    # the same robot on floor 1: the same layout, the other floor's LEDs
    up = plan_leds_per_floor(
        [r], ["1"], ids, pos, floors, lit_now=frozenset(), last_chosen_s=EMPTY, wear_h=EMPTY
    )
    assert {i - 100 for i in up.lit} == set(plan.lit)
    # a single-floor site plans exactly as before
    ids0, pos0 = ids[:24], pos[:24]
    one = plan_leds_per_floor(
        [r], ["0"], ids0, pos0, ["0"] * 24, lit_now=frozenset(), last_chosen_s=EMPTY,
        wear_h=EMPTY,
    )  # fmt: skip
    assert one == plan_leds([r], ids0, pos0, lit_now=frozenset(), last_chosen_s=EMPTY,
                            wear_h=EMPTY)  # fmt: skip


def test_an_identifying_robot_holds_only_its_own_floor_lit() -> None:
    """Floor 1's lit LEDs are not held for a robot identifying on floor 0 (nor lit for it)."""
    ids, pos, floors = two_stacked_floors()
    lit = frozenset(ids)
    plan = plan_leds_per_floor(
        [robot("r1", None, mode="identifying")], ["0"], ids, pos, floors, lit_now=lit,
        last_chosen_s=EMPTY, wear_h=EMPTY,
    )  # fmt: skip
    assert {i for i in ids if i < 200} <= plan.lit
    assert not any("r1" in plan.reasons.get(i, "") for i in ids if i >= 200)
    assert not any(plan.reasons.get(i, "").startswith("held") for i in ids if i >= 200)


def test_mismatched_floor_lists_are_refused() -> None:
    ids, pos, floors = two_stacked_floors()
    with pytest.raises(ValueError, match="2 robots with 1 floors"):
        plan_leds_per_floor(
            [robot("a", None), robot("b", None)], ["0"], ids, pos, floors,
            lit_now=frozenset(), last_chosen_s=EMPTY, wear_h=EMPTY,
        )  # fmt: skip
