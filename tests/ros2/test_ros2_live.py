"""irloc on ROS 2 end to end: the site server (MQTT, the demo world), `irloc agent --ros2
--sim` (a simulated ROS 2 robot driver and the agent on its topics) and an independent DDS
participant (tests/ros2/ros2_listener.py: its own process, ROS 2's definitions only)."""

from __future__ import annotations

import bisect
import json
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.fleet.mosquitto import Mosquitto, mosquitto_binary
from tests.server.conftest import start_api

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        mosquitto_binary() is None,
        reason="Debian's mosquitto is not installed (apt-get install mosquitto)",
    ),
]
ROOT = Path(__file__).resolve().parents[2]
LISTEN_S = 75.0  # at most: the listener stops LINGER_S after its /initialpose
LINGER_S = 12.0  # the relocalized poses (`test_initialpose_relocalizes_the_kidnapped_robot`)
TOLERANCE_NS = 1_000_000_000  # the agent's transform_tolerance_s (map -> odom post-dated)


def kidnap_scenario(path: Path) -> Path:
    """The demo with r1 driving off its dock, then carried to another place and left there
    (the world, and so the site's map, are the demo's)."""
    import sim.scenarios

    demo = yaml.safe_load((Path(sim.scenarios.__file__).parent / "demo.yaml").read_text())
    r1 = next(r for r in demo["robots"] if r["name"] == "r1")
    r1["route"] = {"steps": [
        {"goto": [3.0, 0.6]}, {"wait": 8.0},
        {"kidnap": {"to": [2.2, 2.9, 30.0], "carry_s": 2.0}}, {"wait": 60.0},
    ]}  # fmt: skip
    path.write_text(yaml.safe_dump(demo))
    return path


@dataclass
class Run:
    seen: dict[str, Any]
    agent_log: str
    landmark_ids: set[int]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Run]:
    tmp = tmp_path_factory.mktemp("ros2")
    scenario = kidnap_scenario(tmp / "kidnap.yaml")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ROS_LOCALHOST_ONLY": "1"}
    env["ROS_DOMAIN_ID"] = str(100 + os.getpid() % 100)
    out = tmp / "seen.json"
    with Mosquitto() as broker:
        for api in start_api(tmp, mqtt_url=broker.url, sim_robots=False, mqtt_agents=["r1"]):
            agent = subprocess.Popen(
                [sys.executable, "-m", "irloc", "agent", "--mqtt", broker.url, "--ros2", "--sim",
                 "--name", "r1", "--scenario", str(scenario), "--start-known",
                 "--camera-rate", "10", "--hold", "0.15", "--log-level", "warning"],
                env=env, cwd=ROOT, stderr=subprocess.PIPE, text=True,
            )  # fmt: skip
            try:
                subprocess.run(
                    [sys.executable, str(ROOT / "tests/ros2/ros2_listener.py"),
                     "--domain", env["ROS_DOMAIN_ID"], "--seconds", str(LISTEN_S),
                     "--linger", str(LINGER_S),
                     "--out", str(out),
                     "--topic", "/tf", "--topic", "/r1/irloc/pose", "--topic", "/diagnostics",
                     "--topic", "/r1/irloc/landmarks", "--topic", "/r1/ground_truth",
                     "--truth-topic", "/r1/ground_truth",
                     "--initialpose", "/r1/initialpose@lost,30:truth+0.15,-0.1,0.1"],
                    env={k: v for k, v in env.items() if k != "PYTHONPATH"}, cwd=tmp,
                    check=True, timeout=LISTEN_S + 60,
                )  # fmt: skip
            finally:
                agent.terminate()
                _, err = agent.communicate(timeout=20)
            landmarks = api.client.get("/api/v1/landmarks", headers=api.h("viewer")).json()
            yield Run(json.loads(out.read_text()), err, {lm["id"] for lm in landmarks})


def composed_errors(seen: dict[str, Any], robot: str = "r1") -> list[tuple[int, float]]:
    """(stamp, metres) for each map -> odom received: composed with the robot's own
    odom -> base_link at the pose's stamp (interpolated), against the ground truth."""
    tfs = [t for msg in seen["messages"]["/tf"] for t in msg]
    map_odom = [t for t in tfs if (t["parent"], t["child"]) == ("map", f"{robot}/odom")]
    odom = sorted(
        (t["t"], t)
        for t in tfs
        if (t["parent"], t["child"]) == (f"{robot}/odom", f"{robot}/base_link")
    )
    times = [t for t, _ in odom]
    truth = {g["t"]: g for g in seen["messages"][f"/{robot}/ground_truth"]}
    out = []
    for m in map_odom:
        t = m["t"] - TOLERANCE_NS
        i = bisect.bisect_left(times, t)
        if t not in truth or i == 0 or i >= len(times):
            continue
        a, b = odom[i - 1][1], odom[i][1]
        s = (t - a["t"]) / (b["t"] - a["t"])
        ob = (a["x"] + s * (b["x"] - a["x"]), a["y"] + s * (b["y"] - a["y"]),
              a["yaw"] + s * math.remainder(b["yaw"] - a["yaw"], 2 * math.pi))  # fmt: skip
        c, sn = math.cos(m["yaw"]), math.sin(m["yaw"])
        x = m["x"] + c * ob[0] - sn * ob[1]
        y = m["y"] + sn * ob[0] + c * ob[1]
        out.append((t, math.hypot(x - truth[t]["x"], y - truth[t]["y"])))
    return out


def timeline(seen: dict[str, Any]) -> str:
    """What the diagnostics said, one line per change of mode or problem (seconds after the
    robot's first ground truth): the story of a failed run."""
    t0 = min(g["t"] for g in seen["messages"]["/r1/ground_truth"])
    lines, last = [], None
    for msg in seen["messages"]["/diagnostics"]:
        for s in msg:
            problems = {k: v for k, v in s["values"].items() if k.startswith("problem.")}
            key = (s["values"]["mode"], s["message"], tuple(problems))
            if key != last:
                lines.append(f"{s['values']['mode']}: {s['message']} {problems or ''}")
            last = key
    sent = [f"/initialpose at {(p['t'] - t0) / 1e9:.1f} s" for p in seen["sent"]]
    return "\n".join([*lines, *sent])


def test_a_ros2_participant_sees_ros2_types(run: Run) -> None:
    assert run.seen["types"] == {
        "/tf": "tf2_msgs::msg::dds_::TFMessage_",
        "/r1/irloc/pose": "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_",
        "/diagnostics": "diagnostic_msgs::msg::dds_::DiagnosticArray_",
        "/r1/irloc/landmarks": "visualization_msgs::msg::dds_::MarkerArray_",
        "/r1/ground_truth": "nav_msgs::msg::dds_::Odometry_",
        "/r1/initialpose": "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_",
    }
    markers = run.seen["messages"]["/r1/irloc/landmarks"][-1]
    cylinders = [m for m in markers if m["ns"] == "irloc_landmarks" and m["type"] == 3]
    assert {m["id"] for m in cylinders} == run.landmark_ids  # the site's map, every landmark
    assert all(m["frame"] == "map" and m["z"] > 2 for m in cylinders)
    statuses = [s for msg in run.seen["messages"]["/diagnostics"] for s in msg]
    ok = [s for s in statuses if s["level"] == 0]
    assert ok and ok[-1]["values"]["mode"] == "landmark", (statuses[-3:], run.agent_log[-3000:])
    assert len(ok[-1]["values"]["landmarks_in_use"].split()) >= 2
    assert "Traceback" not in run.agent_log, run.agent_log


def kidnapped_at(seen: dict[str, Any]) -> int:
    """The stamp at which the robot left its route (picked up at (3.0, 0.6))."""
    return min(int(g["t"]) for g in seen["messages"]["/r1/ground_truth"] if g["y"] > 0.62)


def test_map_to_odom_puts_the_robot_within_2_cm_of_the_truth(run: Run) -> None:
    errors = composed_errors(run.seen)
    pose_stamps = [p["t"] for p in run.seen["messages"]["/r1/irloc/pose"]]
    before = [e for t, e in errors if t < kidnapped_at(run.seen)]  # on its route
    assert len(before) > 20, errors
    t0 = min(g["t"] for g in run.seen["messages"]["/r1/ground_truth"])
    far = [(round((t - t0) / 1e9, 1), round(e, 3)) for t, e in errors if e >= 0.02]
    assert max(before) < 0.02, (far[:10], timeline(run.seen))
    assert all(p["frame"] == "map" for p in run.seen["messages"]["/r1/irloc/pose"])
    assert len(pose_stamps) == len(set(pose_stamps))


def test_initialpose_relocalizes_the_kidnapped_robot(run: Run) -> None:
    """Carried off, the robot leaves the landmark mode (dead reckoning, then lost: "send
    /initialpose"); the /initialpose an operator sends then (near the truth; at 30 s at the
    latest when a loaded machine slows the detection) brings it back within 2 cm."""
    statuses = [s for msg in run.seen["messages"]["/diagnostics"] for s in msg]
    assert run.seen["sent"], "no /initialpose was sent"
    sent = run.seen["sent"][0]["t"]
    kidnap = kidnapped_at(run.seen)
    modes = [s["values"]["mode"] for s in statuses]
    assert modes[-1] == "landmark" and {"dead_reckoning", "lost"} & set(modes), timeline(run.seen)
    lost = [s for s in statuses if s["values"]["mode"] == "lost"]
    if run.seen["sent"][0]["when_lost"]:
        assert lost and lost[0]["level"] >= 1 and "initialpose" in lost[0]["message"]
    assert sent > kidnap
    after = [e for t, e in composed_errors(run.seen) if t > sent + 3e9]
    assert len(after) > 20, timeline(run.seen)
    assert max(after) < 0.02, timeline(run.seen)
