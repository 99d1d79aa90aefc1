"""An agent on a site with floors (agent/core.py): it keeps every floor's map, localizes on
the one the site tells it, and when told another floor (it left the lift) publishes no
pose until it holds that floor's map, then identifies again near the lift's node; every
pose names the floor and the map version it was computed on."""

from __future__ import annotations

import numpy as np

from agent.core import AgentConfig, AgentCore, Outgoing
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.payloads import AgentStatus, FloorMessage, MapLandmark, MapMessage, PoseMessage
from sim.scenario import load_scenario
from tests.agent.test_core import MS, FakeSite


def floor_map(records: list[dict[str, object]], floor: str, version: int) -> MapMessage:
    lms = [MapLandmark.model_validate(r) for r in records if r["floor"] == floor]
    return MapMessage(map_id=f"f{floor}-v{version}", landmarks=lms, floor=floor, version=version)


def poses(outs: list[Outgoing]) -> list[PoseMessage]:
    return [PoseMessage.model_validate_json(o.payload) for o in outs if o.kind == "pose"]


def test_told_its_new_floor_the_agent_takes_that_map_and_localizes_there() -> None:
    source = SimRobotSource(load_scenario("two_floors"), "r2", light=True)  # rides 0 -> 1
    core = AgentCore(AgentConfig("a2", source="sim-light", floor="0"), source, TimeBase())
    records = source.world.landmark_records()
    core.on_map(floor_map(records, "0", 3))
    site = FakeSite(core, [int(r["id"]) for r in records])  # type: ignore[call-overload]
    now = core.time.mono_ns()
    core.on_leds(site.state(now, set(site.ids)))
    core.on_floor(FloorMessage(n=1, floor="0", version=3))  # at arrival: where it starts
    before: list[Outgoing] = []
    robot = source.rig.robot
    while not (robot.floor == "1" and not robot.in_lift):  # drive to the lift, ride up
        now += 10 * MS
        outs = core.tick(now)
        site.handle(now, outs)
        before += outs
    assert any(p.mode == "landmark" and (p.floor, p.map_version) == ("0", 3)
               for p in poses(before))  # fmt: skip
    # told at the lift's door, floor 1's map not here yet: no pose goes out
    x, y, th = robot.pose_at(source._t_local_ns)
    core.on_floor(FloorMessage(n=2, floor="1", version=5, near=(x, y, th)))
    waiting: list[Outgoing] = []
    for _ in range(30):
        now += 10 * MS
        waiting += core.tick(now)
    assert poses(waiting) and all(p.x is None and p.floor == "1" for p in poses(waiting))
    core.on_map(floor_map(records, "1", 5))
    core.on_floor(FloorMessage(n=2, floor="1", version=5, near=(x, y, th)))  # retained copy
    after: list[Outgoing] = []
    first_fix_s = None
    for i in range(300):
        now += 10 * MS
        outs = core.tick(now)
        site.handle(now, outs)
        after += outs
        if first_fix_s is None and any(p.mode == "landmark" for p in poses(outs)):
            first_fix_s = (i + 1) * 0.01
    got = [p for p in poses(after) if p.x is not None]
    assert got and all((p.floor, p.map_version) == ("1", 5) for p in got)
    assert first_fix_s is not None and first_fix_s < 3.0, first_fix_s
    fixes = [p for p in got if p.mode == "landmark" and p.y is not None]
    err = []
    for p in fixes[-10:]:
        t = core.time.mono_from_site(p.t_ns)
        truth = min(source.truth.items(), key=lambda kv: abs(kv[0] - t))[1]
        err.append(float(np.hypot(p.x - truth[0], p.y - truth[1])))  # type: ignore[operator]
    assert err and max(err) < 0.05, err
    status = AgentStatus.model_validate_json(core.status(0, 1).encode())
    assert (status.floor, status.map_version, status.map_id) == ("1", 5, "f1-v5")


def test_an_agent_that_knows_no_floor_takes_the_default_floors_map_until_told() -> None:
    source = SimRobotSource(load_scenario("two_floors"), "r3", light=True)  # on floor 1
    core = AgentCore(AgentConfig("a3", source="sim-light"), source, TimeBase())
    records = source.world.landmark_records()
    core.on_map(floor_map(records, "0", 1))  # the legacy `map` topic: the default floor
    core.on_map(floor_map(records, "1", 2))
    core.tick(core.time.mono_ns())
    assert (core.map_floor, core.map_id) == ("0", "f0-v1")
    core.on_floor(FloorMessage(n=7, floor="1", version=2))
    core.tick(core.time.mono_ns())
    assert (core.map_floor, core.map_version, core.floors.wanted) == ("1", 2, "1")


def test_an_agent_that_changes_floors_untold_withholds_its_poses() -> None:
    """r3 rides from floor 1 to floor 0 and nobody tells its agent: from the cabin on its
    view does not fit floor 1's map, so its poses go out without a position, flagged
    `floor_unknown`, and none of floor 1's map is sent while it is on floor 0."""
    source = SimRobotSource(load_scenario("two_floors"), "r3", light=True)
    core = AgentCore(AgentConfig("a3", source="sim-light", floor="1"), source, TimeBase())
    records = source.world.landmark_records()
    core.on_map(floor_map(records, "0", 1))
    core.on_map(floor_map(records, "1", 1))
    site = FakeSite(core, [int(r["id"]) for r in records])  # type: ignore[call-overload]
    now = core.time.mono_ns()
    core.on_leds(site.state(now, set(site.ids)))
    robot = source.rig.robot
    fixed_before = False
    on_floor_0: list[PoseMessage] = []
    off_since = None
    for _ in range(2600):
        now += 10 * MS
        outs = core.tick(now)
        site.handle(now, outs)
        got = poses(outs)
        fixed_before |= robot.floor == "1" and any(p.mode == "landmark" for p in got)
        if robot.floor == "0" and not robot.in_lift:
            off_since = now if off_since is None else off_since
            if now - off_since > 100 * MS:  # frames of the floor held back by the reorder
                on_floor_0 += got
        if off_since is not None and now - off_since > 4000 * MS:
            break
    assert fixed_before and off_since is not None, "r3 never rode down"
    assert on_floor_0 and all(p.x is None for p in on_floor_0), [
        (p.mode, p.floor) for p in on_floor_0 if p.x is not None
    ][:5]
    assert all(p.floor_unknown for p in on_floor_0)
