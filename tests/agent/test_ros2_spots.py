"""A ROS 2 agent's confident frames reach the site like an MQTT agent's: the agent core over
its ROS 2 inputs (`agent.ros2_agent.Ros2SensorSource`) sends each confident pose's spots
once a second, and the site's runner keeps them for map upkeep (`AgentRunner.frame_at`)."""

from __future__ import annotations

from typing import cast

from agent.core import AgentConfig, AgentCore, Outgoing
from agent.ros2_agent import Ros2SensorSource
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.payloads import MapMessage, PoseMessage
from live.agent_runner import AgentRunner
from localizer.events import SpotsObserved
from ros2.health import Health
from sensors.event_buffer import EventBuffer
from sensors.ros2 import Ros2Source
from sim.scenario import load_scenario
from tests.agent.test_core import MS, FakeSite


class Wire:
    """What DDS delivers to `Ros2Source`: the simulated robot's image and odometry, pushed
    into the agent's buffer as the subscriber callbacks would (no DDS here)."""

    def __init__(self, sim: SimRobotSource) -> None:
        self.sim, self.camera, self.geometry = sim, sim.camera, sim.geometry
        self.health = Health("r1")
        self.sink: EventBuffer | None = None

    def start(self, sink: EventBuffer) -> None:
        self.sink = sink

    def stop(self) -> None:
        self.sink = None

    def deliver(self, t_ns: int) -> None:
        assert self.sink is not None
        for e in self.sim.step(t_ns):
            self.sink("r1", e)  # type: ignore[arg-type]

    def ros_stamp(self, t_mono_ns: int) -> int:
        return t_mono_ns


def test_a_ros2_agents_confident_poses_carry_spots_that_its_site_runner_keeps() -> None:
    sim = SimRobotSource(load_scenario("demo"), "r1", light=True)
    wire = Wire(sim)
    source = Ros2SensorSource(cast(Ros2Source, wire), sim.start_pose)
    source.led_sink = sim.apply_leds  # a demo robot's simulated ceiling
    core = AgentCore(AgentConfig("r1", source="sim-light"), source, TimeBase())
    source.start()
    records = sim.world.landmark_records()
    core.on_map(MapMessage(map_id="demo-1", landmarks=records))  # type: ignore[arg-type,call-arg]
    site = FakeSite(core, [int(r["id"]) for r in records])  # type: ignore[call-overload]
    now = core.time.mono_ns()
    core.on_leds(site.state(now, set(site.ids)))
    out: list[Outgoing] = []
    for _ in range(400):
        now += 10 * MS
        wire.deliver(now)
        outs = core.tick(now)
        site.handle(now, outs)
        out += outs
    poses = [PoseMessage.model_validate_json(o.payload) for o in out if o.kind == "pose"]
    with_spots = [p for p in poses if p.spots is not None]
    assert 1 <= len(with_spots) <= 4, len(with_spots)
    runner = AgentRunner(
        "r1", core.status(None, None), publish=lambda u: None,
        send_command=lambda r, n: None, site_from_wall=lambda t: t,
    )  # fmt: skip
    for p in poses:
        runner.receive(p)
    for p in with_spots:
        frame = runner.frame_at(p.t_ns)
        assert isinstance(frame, SpotsObserved) and len(frame.pixels) >= 2
