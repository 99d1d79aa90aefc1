"""Robot agents on a site with floors, end to end with a real Mosquitto: the site server
(`--mqtt`, the two-floor virtual site without its robots) in this process, two agents
(`agent.runtime.AgentRuntime`, spot-level simulation) on a thread of their own so the test
can see where their simulated robots are. Each agent gets its floor's map; one told at the
lift that it is on floor 1 localizes there; a floor's edit reaches the agent on it."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from agent.core import AgentConfig, AgentCore
from agent.runtime import AgentRuntime
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.broker import parse_broker_url
from sim.scenario import load_scenario
from store.models import LandmarkCreate
from tests.agent.test_fleet_live import wait_until
from tests.fleet.mosquitto import Mosquitto, mosquitto_binary
from tests.server.conftest import Api, start_api

pytestmark = pytest.mark.skipif(mosquitto_binary() is None, reason="mosquitto not installed")


@dataclass
class Site:
    api: Api
    sources: dict[str, SimRobotSource]
    cores: dict[str, AgentCore]


class AgentThread:
    """The agents' runtime on its own event loop and thread."""

    def __init__(self, url: str, cores: list[AgentCore]) -> None:
        self.runtime = AgentRuntime(parse_broker_url(url), "default", cores)
        self.loop = asyncio.new_event_loop()
        self.stop_event: asyncio.Event | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        async def go() -> None:
            self.stop_event = asyncio.Event()
            await self.runtime.run(self.stop_event)

        self.loop.run_until_complete(go())

    def stop(self) -> None:
        if self.stop_event is not None:
            self.loop.call_soon_threadsafe(self.stop_event.set)
        self.thread.join(10)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    tmp = tmp_path_factory.mktemp("fleet_floors")
    scenario = load_scenario("two_floors")
    # f2 is r2 (starts on floor 0, rides up); f3 is r3 (starts on floor 1)
    sources = {n: SimRobotSource(scenario, r, light=True) for n, r in (("f2", "r2"), ("f3", "r3"))}
    cores = {
        n: AgentCore(AgentConfig(n, source="sim-light", floor=s.start_floor), s, TimeBase())
        for n, s in sources.items()
    }
    with Mosquitto() as broker:
        for api in start_api(tmp, scenario="two_floors", mqtt_url=broker.url, sim_robots=False,
                             mqtt_agents=list(cores)):  # fmt: skip
            agents = AgentThread(broker.url, list(cores.values()))
            try:
                yield Site(api, sources, cores)
            finally:
                agents.stop()


def pose(s: Site, robot: str) -> dict[str, object]:
    r = s.api.client.get(f"/api/v1/robots/{robot}/pose", headers=s.api.h("viewer"))
    return dict(r.json()) if r.status_code == 200 else {}


def test_each_agent_localizes_on_its_own_floors_map(site: Site) -> None:
    versions = site.api.services.map_versions
    wait_until(lambda: pose(site, "f3").get("mode") == "landmark", 40, "f3 localized")
    p = pose(site, "f3")
    assert (p["floor"], p["map_version"]) == ("1", versions.version("1"))
    assert site.api.services.robots.get("f3").floor == "1"
    truth = site.sources["f3"].truth
    t = min(truth.items(), key=lambda kv: abs(kv[0] - site.cores["f3"]._fed_t_ns))[1]
    assert float(np.hypot(float(p["x"]) - t[0], float(p["y"]) - t[1])) < 0.3  # type: ignore[arg-type]
    assert site.cores["f3"].map_floor == "1" and site.cores["f2"].map_floor == "0"


def test_an_agent_told_at_the_lift_is_localized_on_the_new_floor_within_3_s(site: Site) -> None:
    robot = site.sources["f2"].rig.robot
    wait_until(lambda: robot.floor == "1" and not robot.in_lift, 60, "f2 out of the lift")
    x, y, theta = robot.pose_at(site.sources["f2"]._t_local_ns)  # the lift's door
    with site.api.services.robots.subscribe_poses({"f2"}, maxsize=10_000) as sub:
        told = time.monotonic()
        r = site.api.client.post(
            "/api/v1/robots/f2/floor",
            json={"floor": "1", "near": {"x": x, "y": y, "theta": theta}},
            headers=site.api.h("operator"),
        )
        assert r.status_code in (200, 202), r.text
        fixed_after = None
        seen = []
        while fixed_after is None and time.monotonic() - told < 10:
            time.sleep(0.05)
            for u in sub.drain():
                seen.append(u)
                if u.mode == "landmark" and u.x is not None and u.floor == "1":
                    fixed_after = time.monotonic() - told
    assert fixed_after is not None and fixed_after < 3.0, fixed_after
    assert all(u.floor == "1" for u in seen if u.x is not None), [
        (u.floor, u.mode) for u in seen if u.x is not None and u.floor != "1"
    ]
    assert site.cores["f2"].map_floor == "1"
    assert pose(site, "f2")["map_version"] == site.api.services.map_versions.version("1")


def test_an_edit_of_a_floor_reaches_the_agent_on_it_with_its_version(site: Site) -> None:
    services = site.api.services
    before = services.map_versions.version("1")
    services.map.create(LandmarkCreate(id=599, x=20.0, y=20.0, z=2.8, floor="1"), actor="test")
    after = services.map_versions.version("1")
    assert after == before + 1
    wait_until(lambda: site.cores["f3"].map_version == after, 10, f"f3 took version {after}")
    wait_until(lambda: pose(site, "f3").get("map_version") == after, 10, "f3's poses say so")
    assert site.cores["f3"].map_floor == "1"
