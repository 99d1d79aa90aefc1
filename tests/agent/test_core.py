"""The agent's localization loop without a network (agent/core.py, agent/sim_source.py):
the site's LED coordinator is played by a few lines that confirm each request."""

from __future__ import annotations

import itertools
import json

import numpy as np

from agent.core import AgentConfig, AgentCore, Outgoing
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.payloads import (
    AgentStatus,
    CommandMessage,
    LedRequestMessage,
    LedStateMessage,
    MapMessage,
    PoseMessage,
)
from sim.scenario import load_scenario
from tests.fleet.vda import validate_vda

MS = 1_000_000


class FakeSite:
    """Confirms every LED request 20 ms after announcing it (radio latency)."""

    def __init__(self, core: AgentCore, landmark_ids: list[int]) -> None:
        self.core, self.ids, self.seq = core, landmark_ids, 0
        self.pending: list[tuple[int, LedStateMessage]] = []
        self.requests = 0

    def state(
        self, t_mono: int, lit: set[int], changing: set[int] | None = None
    ) -> LedStateMessage:
        self.seq += 1
        all_lit = lit == set(self.ids)
        return LedStateMessage(
            seq=self.seq, t_ns=self.core.time.site_from_mono(t_mono),
            lit=[] if all_lit else sorted(lit), all_lit=all_lit, changing=sorted(changing or ()),
        )  # fmt: skip

    def handle(self, now: int, outs: list[Outgoing]) -> None:
        for o in outs:
            if o.kind == "led_request":
                self.requests += 1
                req = LedRequestMessage.model_validate_json(o.payload).request()
                lit = set(self.ids) - set(req.dark) if req.all_lit else set(req.lit)
                changing = set(self.ids) ^ lit  # the last confirmed state is all lit here
                if changing:
                    self.core.on_leds(self.state(now, set(self.ids), changing))
                self.pending.append((now + 20 * MS, self.state(now + 20 * MS, lit)))
        for due, msg in list(self.pending):
            if due <= now:
                self.core.on_leds(msg)
                self.pending.remove((due, msg))


def run(light: bool, seconds: float) -> tuple[AgentCore, FakeSite, list[Outgoing]]:
    scenario = load_scenario("demo")
    source = SimRobotSource(scenario, "r1", light=light)
    core = AgentCore(AgentConfig("a1", source="sim-light" if light else "sim"), source, TimeBase())
    records = source.world.landmark_records()
    core.on_map(MapMessage(map_id="demo-1", landmarks=records))  # type: ignore[arg-type]
    site = FakeSite(core, [int(r["id"]) for r in records])  # type: ignore[call-overload]
    now = core.time.mono_ns()
    core.on_leds(site.state(now, set(site.ids)))
    out: list[Outgoing] = []
    for _ in range(int(seconds / 0.01)):
        now += 10 * MS
        outs = core.tick(now)
        site.handle(now, outs)
        out += outs
    return core, site, out


def test_light_agent_identifies_through_led_requests_and_tracks_the_truth() -> None:
    core, site, out = run(light=True, seconds=4.0)
    assert core.mode == "landmark" and site.requests >= 2
    poses = [PoseMessage.model_validate_json(o.payload) for o in out if o.kind == "pose"]
    fixes = [p for p in poses if p.mode == "landmark"]
    # 10 poses a second at most once tracking (mode changes go at once)
    assert 25 <= len(fixes) <= 40
    src = core.source
    assert isinstance(src, SimRobotSource)
    errors = []
    for p in fixes:
        t = core.time.mono_from_site(p.t_ns)
        truth = min(src.truth.items(), key=lambda kv: abs(kv[0] - t))[1]
        errors.append(np.hypot(p.x - truth[0], p.y - truth[1]))  # type: ignore[operator]
    assert np.median(errors) < 0.02, np.median(errors)
    vis = [json.loads(o.payload) for o in out if o.kind == "visualization"]
    assert 3 <= len(vis) <= 8
    for v in vis:
        validate_vda("visualization", v)


def test_rendered_agent_localizes_too() -> None:
    core, _site, _ = run(light=False, seconds=2.5)
    assert core.mode == "landmark" and core.frames >= 60 and core.errors == 0


def test_duplicate_and_late_led_states_and_a_relocalize_command() -> None:
    core, site, _ = run(light=True, seconds=2.0)
    states = core.led_states
    last = site.state(core.time.mono_ns() - 5 * 10**9, set(site.ids))
    core.on_leds(last)
    core.on_leds(last)  # the retained copy after a reconnect
    core.on_command(CommandMessage(command="relocalize"))
    core.tick(core._fed_t_ns + 40 * MS)
    assert core.led_states == states + 1 and core.late_leds == 1
    assert core.mode == "identifying"
    status = core.status(-3, 1)
    assert AgentStatus.model_validate_json(status.encode()).camera["sensor_type"] == "camera"


def test_confident_poses_carry_their_spots_once_a_second() -> None:
    _, _, out = run(light=True, seconds=4.0)
    poses = [PoseMessage.model_validate_json(o.payload) for o in out if o.kind == "pose"]
    with_spots = [p for p in poses if p.spots is not None]
    assert 1 <= len(with_spots) <= 4  # 1 s apart, from the first confident fix on
    for p in with_spots:
        assert p.mode == "landmark" and len(p.lm) >= 2 and len(p.spots or []) >= 2
        assert p.ex is not None  # the landmarks expected in view go with them (pairing)
    ts = [p.t_ns for p in with_spots]
    assert all(b - a >= 0.99e9 for a, b in itertools.pairwise(ts))


def test_a_dock_prior_holds_for_the_first_sample_when_the_map_comes_late() -> None:
    """`start_known`: the dock pose is where the robot was at its first sample; a map that
    arrives 1.5 s later (the robot already driving) starts the localizer there and replays
    the wheels since, instead of pinning the dock pose on a robot that has moved."""
    scenario = load_scenario("demo")
    source = SimRobotSource(scenario, "r1", light=True)
    cfg = AgentConfig("a1", source="sim-light", start_known=True)
    core = AgentCore(cfg, source, TimeBase())
    records = source.world.landmark_records()
    site = FakeSite(core, [int(r["id"]) for r in records])  # type: ignore[call-overload]
    now = core.time.mono_ns()
    core.on_leds(site.state(now, set(site.ids)))
    start = now
    out: list[Outgoing] = []
    for _ in range(250):
        now += 10 * MS
        if now - start == 1500 * MS:
            core.on_map(MapMessage(map_id="demo-1", landmarks=records))  # type: ignore[arg-type]
        outs = core.tick(now)
        site.handle(now, outs)
        out += outs
    poses = [PoseMessage.model_validate_json(o.payload) for o in out if o.kind == "pose"]
    assert poses, "no pose after the map arrived"
    truths = sorted(source.truth.items())
    moved = np.hypot(*(np.subtract(truths[-1][1][:2], truths[0][1][:2])))
    assert moved > 0.2, moved  # the robot drove off its dock before the map came
    first = poses[0]
    t = core.time.mono_from_site(first.t_ns)
    truth = min(truths, key=lambda kv: abs(kv[0] - t))[1]
    assert np.hypot(first.x - truth[0], first.y - truth[1]) < 0.05  # type: ignore[operator]
