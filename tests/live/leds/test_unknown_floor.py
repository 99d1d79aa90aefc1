"""A robot whose floor is unknown (`fleet.floor_fit`) is planned on every floor by the LED
schedule, at its latest pose there: the ceiling it is really under is lit for it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agent.sim_source import SimRobotSource
from fleet.floor_fit import FloorFit, FloorFitConfig
from live.leds.runtime import LedScheduler
from live.poses import PoseUpdate
from localizer.camera import CameraModel
from localizer.events import Mode, PoseEstimate
from sim.scenario import load_scenario

MS = 1_000_000


@dataclass
class Runner:
    name: str
    camera: CameraModel
    floor: str
    latest: PoseUpdate | None
    floor_fit: FloorFit | None
    mode: Mode = "dead_reckoning"


def plan_for(fit: FloorFit) -> frozenset[int]:
    scenario = load_scenario("two_floors")
    source = SimRobotSource(scenario, "r3", light=True)
    records = source.world.landmark_records()
    ids = [int(r["id"]) for r in records]  # type: ignore[call-overload]
    xyz = np.array([[r["x"], r["y"], r["z"]] for r in records], dtype=np.float64)
    floors = {int(r["id"]): str(r["floor"]) for r in records}  # type: ignore[call-overload]
    runner = Runner("r3", source.camera, "1", PoseUpdate("r3", 0, "dead_reckoning"), fit)
    scheduler = LedScheduler(
        lambda: (ids, xyz), lambda: [runner], lambda name: 0.8, lambda: None, lambda: 0,
        floors=lambda: floors,
    )  # fmt: skip
    return scheduler.step(2000 * MS).lit


def test_an_unknown_floor_robot_gets_the_other_floors_ceiling_lit_around_it() -> None:
    fit = FloorFit(FloorFitConfig(unfit_after_s=0.5))
    for t in range(0, 700, 100):  # by the lift, landmarks expected, none seen
        est = PoseEstimate(t * MS, 6.0, 2.4, 0.0, np.eye(3) * 1e-3, "dead_reckoning", (),
                           (500, 501))  # fmt: skip
        fit.observe(est)
    assert fit.unknown
    lit = plan_for(fit)
    assert any(i // 100 in (1, 2) for i in lit)  # floor 0's landmarks (1xx, 2xx) near it
    known = FloorFit()
    assert not any(i // 100 in (1, 2) for i in plan_for(known))  # only floor 1's otherwise
