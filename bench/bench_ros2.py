"""The on-robot agent on ROS 2 against the same agent reading a device: latency from a
frame's publication to its pose's reception, and the agent's CPU per robot, at 30 Hz,
640 x 480 mono8.

    python bench/bench_ros2.py [--seconds 30] [--holds 0.1,0.03]

Frames: robot r1 of the demo site rendered for 10 s at 30 Hz (640 x 480, the fisheye
lens), played forwards then backwards (a robot reversing: no jump) for `--seconds`. The
agent (`AgentCore`, its own process, the map given directly and its start pose known: no
site server in the loop) reads them. Pre-rendered frames cannot answer LED switching, so
the localizer stays in its identifying mode on the start prior: full-frame spot detection
on every frame, its costliest path (tracking searches windows only); both inputs feed it
the same way, so the difference is the input path. It reads them

- from ROS 2 (`Ros2Source`): this process publishes each frame as `sensor_msgs/Image`
  (best effort) on a loopback DDS domain and receives `/r1/irloc/pose`; latency = pose
  reception minus frame publication, the agent's reorder hold included (`--holds`);
- from a device (`HardwareSource`): the same frames as an uncompressed video file, read by
  OpenCV at 30 Hz (what `irloc agent --camera` does).

This process also publishes the robot's `odom -> base_link` on `/tf` with each frame, so
the agent computes and publishes `map -> odom` too.

CPU: the agent process's user + system time over the measured seconds (after 5 s of warm-
up), in % of one core, and per frame (the device reader paces itself after each read, so it
may run below 30 Hz on a loaded machine: compare per frame). Camera only in both (no
odometry): the cost compared is the camera path. One run on a shared machine; the ratio is
the figure to compare.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agent.core import AgentConfig, AgentCore  # noqa: E402
from agent.sim_source import SimRobotSource  # noqa: E402
from agent.timebase import TimeBase  # noqa: E402
from fleet.payloads import LedStateMessage, MapLandmark, MapMessage  # noqa: E402
from sim.scenario import load_scenario  # noqa: E402

WARMUP_S = 5.0
RATE_HZ = 30.0
NS = 1_000_000_000


def render(tmp: Path, seconds: float = 10.0) -> dict[str, Any]:
    """Frames of r1 (npy), the same as an uncompressed video, the map and the start pose."""
    src = SimRobotSource(load_scenario("demo"), "r1")
    src.step(0)
    frames = []
    t = 0
    while len(frames) < seconds * RATE_HZ:
        t += 10_000_000
        frames += [e.image for e in src.step(t) if hasattr(e, "image")]
    stack = np.stack(frames)
    np.save(tmp / "frames.npy", stack)
    h, w = stack.shape[1:]
    video = tmp / "frames.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"Y800"), RATE_HZ, (w, h), False)
    for f in np.concatenate([stack, stack[::-1]]):
        writer.write(f)
    writer.release()
    info = {"map": src.world.landmark_records(), "start": list(src.start_pose)}
    (tmp / "site.json").write_text(json.dumps(info))
    return info


# -- the agent under test (its own process) ------------------------------------------------
def run_agent(args: argparse.Namespace) -> None:
    tmp = Path(args.data)
    site = json.loads((tmp / "site.json").read_text())
    sim = SimRobotSource(load_scenario("demo"), "r1")
    camera, geometry = sim.camera, sim.geometry
    extra: list[Any] = []
    if args.source == "ros2":
        from agent.ros2_agent import Ros2SensorSource
        from ros2.outputs import Ros2Outputs
        from ros2.settings import Ros2Settings
        from ros2.transport import Ros2Participant
        from sensors.ros2 import Ros2Source

        node = Ros2Participant()
        # pre-rendered frames cannot answer LED switching: the localizer stays identifying
        # (on its start prior), and its poses go out anyway to be timed
        modes = ("identifying", "landmark", "dead_reckoning")
        settings = Ros2Settings(namespace="r1", publish_modes=modes)
        source: Any = Ros2SensorSource(Ros2Source("r1", node, settings, geometry, camera=camera))
        outputs = Ros2Outputs(node, settings, source.health, source.ros_stamp, name="r1")
        extra += [outputs, source]
    else:
        from agent.hardware import HardwareSource

        # the video's own decoding and the reader's pacing: as `irloc agent --camera FILE`
        source = HardwareSource(camera, geometry, device=str(tmp / "frames.avi"), wheels=None)
        extra.append(source)
    config = AgentConfig(name="r1", source="camera", reorder_hold_s=args.hold, pose_rate_hz=0)
    core = AgentCore(config, source, TimeBase())
    if args.source == "ros2":
        core.observers.append(extra[0])
    landmarks = [MapLandmark(**{k: v for k, v in lm.items() if k != "radio"}) for lm in site["map"]]
    core.on_map(MapMessage(map_id="bench", landmarks=landmarks))
    core.on_leds(LedStateMessage(seq=0, t_ns=time.time_ns(), all_lit=True))
    for e in extra:
        e.start()
    core.tick(time.monotonic_ns())
    assert core.localizer is not None
    core.localizer.set_initial_pose(*site["start"], time.monotonic_ns() - NS)
    print("ready", flush=True)
    end = time.monotonic() + args.seconds
    mark: tuple[float, float, int, int] | None = None
    next_t = time.monotonic()
    while time.monotonic() < end:
        core.tick(time.monotonic_ns())
        if mark is None and time.monotonic() > end - args.seconds + WARMUP_S:
            r = resource.getrusage(resource.RUSAGE_SELF)
            mark = (r.ru_utime + r.ru_stime, time.monotonic(), core.frames, core.poses)
        next_t += 0.01
        time.sleep(max(0.0, next_t - time.monotonic()))
    r = resource.getrusage(resource.RUSAGE_SELF)
    assert mark is not None
    cpu, wall = r.ru_utime + r.ru_stime - mark[0], time.monotonic() - mark[1]
    modes = core.mode
    for e in extra:
        e.stop()
    print(
        json.dumps(
            {
                "cpu_pct": 100 * cpu / wall,
                "frames_s": (core.frames - mark[2]) / wall,
                "poses_s": (core.poses - mark[3]) / wall,
                "mode": modes,
            }
        ),
        flush=True,
    )


# -- the robot's camera driver and the pose listener (this process) --------------------------
def publish_and_listen(tmp: Path, seconds: float, agent: subprocess.Popen[str]) -> list[float]:
    from ros2.messages import header, new, stamp_ns, transform_stamped
    from ros2.transport import QOS_SENSOR_DATA, QosProfile, Ros2Participant

    frames = np.load(tmp / "frames.npy")
    frames = np.concatenate([frames, frames[::-1]])
    node = Ros2Participant()
    pub = node.publisher("/r1/image_raw", "sensor_msgs/msg/Image", QOS_SENSOR_DATA)
    tf_pub = node.publisher("/tf", "tf2_msgs/msg/TFMessage", QosProfile(depth=100))
    sent: dict[int, int] = {}
    latencies: list[float] = []
    lock = threading.Lock()

    def on_pose(msg: Any) -> None:
        now = time.monotonic_ns()
        with lock:
            t_pub = sent.pop(stamp_ns(msg.header.stamp), None)
        if t_pub is not None:
            latencies.append((now - t_pub) / 1e6)

    node.subscribe("/r1/irloc/pose", "geometry_msgs/msg/PoseWithCovarianceStamped", on_pose)
    time.sleep(1.0)  # discovery
    h, w = frames.shape[1:]
    period = 1.0 / RATE_HZ
    start = time.monotonic()
    next_t = start
    i = 0
    while time.monotonic() - start < seconds and agent.poll() is None:
        stamp = time.time_ns()
        msg = new(
            "sensor_msgs/msg/Image",
            header=header(stamp, "r1/camera_optical_frame"),
            height=h,
            width=w,
            encoding="mono8",
            step=w,
            data=frames[i % len(frames)].tobytes(),
        )
        with lock:
            sent[stamp] = time.monotonic_ns()
        # the robot's odom -> base_link (standing still), as a driver publishes it with odometry
        tf_pub.publish(
            new(
                "tf2_msgs/msg/TFMessage",
                transforms=[
                    transform_stamped(stamp + d, "r1/odom", "r1/base_link", (0.0, 0.0, 0.0))
                    for d in (-1_000_000, 1_000_000)
                ],
            )
        )
        pub.publish(msg)
        if time.monotonic() - start < WARMUP_S:
            latencies.clear()
        i += 1
        next_t += period
        time.sleep(max(0.0, next_t - time.monotonic()))
    node.close()
    return latencies


def measure(tmp: Path, source: str, hold: float, seconds: float) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [
        sys.executable,
        __file__,
        "--role",
        "agent",
        "--source",
        source,
        "--hold",
        str(hold),
        "--data",
        str(tmp),
        "--seconds",
        str(seconds + 1.0),
    ]
    agent = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
    assert agent.stdout is not None
    assert agent.stdout.readline().strip() == "ready"
    latencies = publish_and_listen(tmp, seconds, agent) if source == "ros2" else []
    out, _ = agent.communicate(timeout=seconds + 60)
    result: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    if latencies:
        result["p50_ms"] = float(np.percentile(latencies, 50))
        result["p99_ms"] = float(np.percentile(latencies, 99))
        result["n"] = len(latencies)
    return result


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--holds", default="0.1,0.03", help="the ROS 2 agent's reorder holds, s")
    p.add_argument("--role", choices=["bench", "agent"], default="bench")
    p.add_argument("--source", choices=["ros2", "device"], default="ros2")
    p.add_argument("--hold", type=float, default=0.1)
    p.add_argument("--data")
    args = p.parse_args()
    if args.role == "agent":
        run_agent(args)
        return
    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 80))
    os.environ["ROS_LOCALHOST_ONLY"] = "1"
    with tempfile.TemporaryDirectory(prefix="irloc-bench-ros2-") as d:
        tmp = Path(d)
        render(tmp)
        rows = [("device (video file, OpenCV)", measure(tmp, "device", 0.03, args.seconds))]
        for hold in (float(h) for h in args.holds.split(",")):
            rows.append(
                (f"ROS 2 (hold {hold * 1000:.0f} ms)", measure(tmp, "ros2", hold, args.seconds))
            )
    print(f"load average {os.getloadavg()[0]:.1f}; {args.seconds:.0f} s a row, 30 Hz 640x480 mono8")
    print(
        "| agent input | frames/s | poses/s | final mode | CPU (% core) | CPU per frame (ms) "
        "| latency p50 / p99 (ms) |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, r in rows:
        lat = f"{r['p50_ms']:.1f} / {r['p99_ms']:.1f}" if "p50_ms" in r else "-"
        per_frame = 10 * r["cpu_pct"] / max(r["frames_s"], 1e-9)
        print(
            f"| {name} | {r['frames_s']:.1f} | {r['poses_s']:.1f} | {r['mode']} | "
            f"{r['cpu_pct']:.1f} | {per_frame:.2f} | {lat} |"
        )


if __name__ == "__main__":
    main()
