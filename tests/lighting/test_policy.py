"""The LED schedule's decisions (lighting/policy.py) on hand-made situations."""

from __future__ import annotations

import math

import numpy as np

from lighting.camera_view import body_pose, in_view
from lighting.policy import RobotState, ScheduleConfig, plan_leds
from localizer.camera import CameraModel, predict_pixels
from sim.cameras import wide_angle_camera

CAM = wide_angle_camera("pinhole")
SIGMA = np.diag([0.01**2, 0.01**2, 0.005**2])


def grid(nx: int, ny: int, spacing: float) -> tuple[list[int], np.ndarray]:
    ids, pos = [], []
    for j in range(ny):
        for i in range(nx):
            ids.append(100 + j * nx + i)
            pos.append((i * spacing, j * spacing, 2.5))
    return ids, np.array(pos, dtype=np.float64)


def robot(
    name: str,
    pose: tuple[float, float, float] | None,
    *,
    v: float = 0.0,
    mode: str = "landmark",
    still_s: float = 0.0,
    cov: np.ndarray | None = SIGMA,
    camera: CameraModel = CAM,
) -> RobotState:
    return RobotState(
        name, camera, 1.0, mode, pose, covariance=None if pose is None else cov,  # type: ignore[arg-type]
        v=v, still_s=still_s,
    )  # fmt: skip


def visible(pose: tuple[float, float, float], positions: np.ndarray) -> set[int]:
    px, valid = predict_pixels(CAM, body_pose(*pose), positions)
    ok = valid & (px[:, 0] >= 0) & (px[:, 0] <= 639) & (px[:, 1] >= 0) & (px[:, 1] <= 479)
    return {int(k) for k in np.flatnonzero(ok)}


def test_a_robot_heading_for_a_dark_region_gets_it_lit_before_it_sees_it() -> None:
    """A robot drives along a corridor of landmarks at 1 m/s; each plan (every 0.25 s) is
    applied `latency_s` later. Every landmark must be lit by a plan made at least the
    latency before the robot first sees it, and at every moment the robot has at least two
    lit landmarks in view once it is under the corridor."""
    ids, pos = grid(20, 1, 1.5)
    cfg = ScheduleConfig(latency_s=1.2)
    lit: frozenset[int] = frozenset()
    chosen: dict[int, float] = {}
    lit_since: dict[int, float] = {}
    first_seen: dict[int, float] = {}
    t = 0.0
    while t < 20.0:
        pose = (t * 1.0, 0.0, 0.0)
        for k in visible(pose, pos):
            first_seen.setdefault(ids[k], t)
        plan = plan_leds(
            [robot("r1", pose, v=1.0)], ids, pos, lit_now=lit,
            last_chosen_s={i: t - c for i, c in chosen.items()}, wear_h={}, config=cfg,
        )  # fmt: skip
        for i in plan.wanted:
            chosen[i] = t
        for i in plan.lit - lit:
            lit_since.setdefault(i, t)
        lit = plan.lit
        lit_in_view = {ids[k] for k in visible(pose, pos)} & lit
        if t > 2.0:
            assert len(lit_in_view) >= 2, (t, lit_in_view)
        t += 0.25
    ahead = [i for i in ids if first_seen.get(i, math.inf) > 3.0 and i in first_seen]
    assert len(ahead) >= 8
    for i in ahead:
        assert lit_since[i] <= first_seen[i] - cfg.latency_s, (i, lit_since[i], first_seen[i])


def test_only_a_few_well_spread_landmarks_of_a_dense_view_are_lit() -> None:
    ids, pos = grid(8, 8, 0.6)
    state = robot("r1", (2.1, 2.1, 0.3))
    plan = plan_leds([state], ids, pos, lit_now=frozenset(), last_chosen_s={}, wear_h={},
                     config=ScheduleConfig(horizon_s=0.0))  # fmt: skip
    in_sight = {ids[k] for k in visible((2.1, 2.1, 0.3), pos)}
    assert len(in_sight) >= 16
    assert 2 <= len(plan.lit) <= 4
    assert plan.lit <= in_sight
    xy = {i: pos[ids.index(i), :2] for i in plan.lit}
    spread = min(float(np.hypot(*(xy[a] - xy[b]))) for a in plan.lit for b in plan.lit if a < b)
    assert spread >= 1.0  # not neighbours 0.6 m apart


def test_wear_moves_the_choice_to_landmarks_lit_less() -> None:
    ids, pos = grid(8, 8, 0.6)
    state = robot("r1", (2.1, 2.1, 0.0))
    cfg = ScheduleConfig(horizon_s=0.0)
    first = plan_leds([state], ids, pos, lit_now=frozenset(), last_chosen_s={}, wear_h={},
                      config=cfg)  # fmt: skip
    worn = {i: 50.0 for i in first.lit}
    second = plan_leds([state], ids, pos, lit_now=frozenset(), last_chosen_s={}, wear_h=worn,
                       config=cfg)  # fmt: skip
    assert not first.lit & second.lit


def test_an_idle_site_darkens() -> None:
    ids, pos = grid(6, 4, 1.2)
    parked = [
        robot("r1", (1.0, 1.0, 0.0), still_s=60.0),
        robot("r2", (4.0, 2.0, 1.0), still_s=60.0),
    ]
    lit = frozenset(ids)
    plan = plan_leds(parked, ids, pos, lit_now=lit, last_chosen_s={i: 30.0 for i in ids},
                     wear_h={})  # fmt: skip
    assert plan.lit == frozenset()
    # Recently chosen landmarks are held a moment (no flapping), then darkened.
    held = plan_leds(parked, ids, pos, lit_now=lit, last_chosen_s={i: 0.2 for i in ids},
                     wear_h={})  # fmt: skip
    assert held.lit == lit
    assert set(held.reasons.values()) == {"held"}


def test_a_parked_robot_with_lit_landmarks_in_view_gets_a_full_set() -> None:
    """Another robot's landmarks at the edge of a parked robot's view: the parked one gets
    its own pair too (a single lit landmark in view makes a localizer doubt its pose)."""
    ids, pos = grid(10, 3, 1.2)
    parked = robot("p", (3.0, 1.2, 0.0), still_s=60.0)
    ok, _ = in_view(CAM, (3.0, 1.2, 0.0), pos, 0.0, 2.5)
    parked_view = {ids[k] for k in np.flatnonzero(ok)}
    cfg = ScheduleConfig(horizon_s=0.0)
    for x in np.arange(4.0, 9.0, 0.1):  # where the mover's choice puts one at the edge
        mover = robot("m", (float(x), 1.2, 0.0), v=0.5)
        mover_only = plan_leds([mover], ids, pos, lit_now=frozenset(), last_chosen_s={},
                               wear_h={}, config=cfg)  # fmt: skip
        if len(mover_only.lit & parked_view) == 1:
            break
    else:
        raise AssertionError("no situation with one of the mover's landmarks in view")
    plan = plan_leds([parked, mover], ids, pos, lit_now=frozenset(), last_chosen_s={},
                     wear_h={}, config=cfg)  # fmt: skip
    assert len(plan.lit & parked_view) >= 2
    assert any("parked" in r for r in plan.reasons.values())
    alone = plan_leds([parked], ids, pos, lit_now=frozenset(), last_chosen_s={}, wear_h={})
    assert alone.lit == frozenset()


def test_identification_keeps_the_robots_neighbourhood_lit_and_nothing_is_darkened() -> None:
    ids, pos = grid(10, 10, 1.5)
    # No pose at all: every landmark (the robot may be under any of them).
    plan = plan_leds([robot("r1", None, mode="identifying")], ids, pos, lit_now=frozenset(),
                     last_chosen_s={}, wear_h={},
                     config=ScheduleConfig(max_switches=100))  # fmt: skip
    assert plan.lit == frozenset(ids)
    assert set(plan.reasons.values()) == {"area r1"}
    # Lost with a prior: its neighbourhood, not the far corner.
    lost = robot("r1", (1.5, 1.5, 0.0), mode="lost", cov=np.diag([0.2**2, 0.2**2, 0.1]))
    near = plan_leds([lost], ids, pos, lit_now=frozenset(), last_chosen_s={}, wear_h={})
    assert ids[0] in near.lit and ids[-1] not in near.lit
    # While one robot identifies, what others no longer need stays lit (a switch would
    # spoil the identifying robot's evidence).
    tracker = robot("r2", (12.0, 12.0, 0.0), still_s=60.0)
    lit = frozenset(ids[:30])
    frozen = plan_leds([tracker, lost], ids, pos, lit_now=lit, last_chosen_s={}, wear_h={})
    assert lit <= frozen.lit


def test_the_command_budget_lights_what_is_needed_soonest_first() -> None:
    ids, pos = grid(10, 10, 1.5)
    cfg = ScheduleConfig(max_switches=3)
    lit = frozenset(ids[50:])  # far from the robot, to be darkened
    plan = plan_leds([robot("r1", (1.5, 1.5, 0.0), v=0.5)], ids, pos, lit_now=lit,
                     last_chosen_s={}, wear_h={}, config=cfg)  # fmt: skip
    assert len(plan.lit ^ lit) == 3
    assert plan.lit - lit  # the lights came first
    assert plan.deferred > 0


def test_a_landmark_needed_later_than_the_latency_is_planned_not_lit_yet() -> None:
    """A robot at 1 m/s with a 0.3 s latency and a 2 s horizon: the landmarks it reaches
    only after the latency are chosen (`planned`) but not lit yet: lighting them now would
    only burn their cells."""
    ids, pos = grid(20, 1, 1.5)
    cfg = ScheduleConfig(latency_s=0.3, horizon_s=2.0)
    plan = plan_leds([robot("r1", (3.0, 0.0, 0.0), v=1.0)], ids, pos, lit_now=frozenset(),
                     last_chosen_s={}, wear_h={}, config=cfg)  # fmt: skip
    now = {ids[k] for k in visible((3.0, 0.0, 0.0), pos)}
    assert plan.lit and plan.lit <= now | {ids[k] for k in visible((3.6, 0.0, 0.0), pos)}
    assert plan.planned and not plan.planned & plan.lit
    assert all(ids.index(i) * 1.5 > 3.0 for i in plan.planned)  # ahead of the robot


def test_landmarks_a_tracking_robot_sees_stay_lit_until_its_new_ones_are_confirmed() -> None:
    """The schedule moves a robot to other landmarks (its old ones are worn); while the new
    ones are still being switched (not confirmed), the old ones in its view are not darkened
    (it would have nothing to track); once the new ones are confirmed, the old ones go dark."""
    ids, pos = grid(12, 3, 1.0)
    pose = (6.0, 1.0, 0.0)
    seen = sorted(ids[k] for k in visible(pose, pos))
    assert len(seen) >= 8
    old = frozenset(seen[:3])
    worn = {i: 100.0 for i in old}
    cfg = ScheduleConfig(horizon_s=0.0, hold_s=0.0)
    first = plan_leds([robot("r1", pose)], ids, pos, lit_now=old, last_chosen_s={},
                      wear_h=worn, config=cfg, confirmed=frozenset())  # fmt: skip
    assert old <= first.lit
    assert {first.reasons[i] for i in old} == {"seen r1 (until its new ones are lit)"}
    new = first.lit - old
    assert len(new) == 3 and new <= set(seen)
    later = plan_leds([robot("r1", pose)], ids, pos, lit_now=first.lit, last_chosen_s={},
                      wear_h=worn, config=cfg, confirmed=first.lit)  # fmt: skip
    assert later.lit == new
