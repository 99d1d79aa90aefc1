"""`irloc agent`: the on-robot process. It localizes the robot with the same localizer as the
server, on the site's map and LED states received over MQTT, and publishes its poses (irloc
JSON and VDA 5050).

    irloc agent --mqtt mqtt://HOST:PORT --name NAME --sim [--light]
    irloc agent --mqtt mqtt://HOST:PORT --name NAME --camera DEV --wheels PORT \
        --sensor cam0/sensor.yaml --wheel-base M
    irloc agent --mqtt mqtt://HOST:PORT --name NAME --ros2 --wheel-base M \
        [--sensor cam0/sensor.yaml] [--ros2-namespace NS] [--ros2-param KEY=VALUE ...]

`--sim`: one robot of the site's scenario simulated on the agent (rendered frames; `--light`:
spot-level simulation, no rendering, for many agents on one machine). `--count N` runs N
robots in this process (NAME-000 ...), cycling through the scenario's robots. `--camera` and
`--wheels`: the robot's own camera (OpenCV device, video file or image sequence) and wheel
speeds (`$IRODO` lines on a serial port), with its calibrated `sensor.yaml`. `--ros2`: the
robot's ROS 2 topics instead (docs/ros2.md); with `--sim` each robot of the scenario (`--name
all`: every one) also gets a simulated ROS 2 driver in this process.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import logging
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

from agent.core import AgentConfig, AgentCore
from agent.hardware import HardwareSource
from agent.runtime import AgentRuntime
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.broker import parse_broker_url
from fleet.topics import check_name
from localizer.robot import RobotGeometry
from sim.scenario import Scenario

log = logging.getLogger(__name__)


class Startable(Protocol):
    """What runs beside the network loop (a device reader, a ROS 2 robot's publishers)."""

    def start(self) -> None: ...
    def stop(self) -> None: ...


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="irloc agent", description=__doc__.splitlines()[0])
    p.add_argument("--mqtt", required=True, help="the site's broker, mqtt[s]://[USER@]HOST[:PORT]")
    p.add_argument(
        "--mqtt-password-file",
        type=Path,
        help="the broker password of USER (first line; else $IRLOC_MQTT_PASSWORD)",
    )
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=30.0,
        help="give up (exit 1) when the broker cannot be reached for this long at start, "
        "seconds (0: keep trying; once connected, it always reconnects)",
    )
    p.add_argument("--mqtt-ca", type=Path, help="mqtts: the CA file that signed the broker")
    p.add_argument("--mqtt-cert", type=Path, help="mqtts: this agent's client certificate")
    p.add_argument("--mqtt-key", type=Path, help="mqtts: its private key")
    p.add_argument("--name", required=True, help="the robot's name (VDA 5050 serial number)")
    p.add_argument("--site", default="default", help="site name in the topics (default default)")
    p.add_argument("--manufacturer", default="irloc", help="VDA 5050 manufacturer")
    p.add_argument("--sim", action="store_true", help="simulate a robot of the site's scenario")
    p.add_argument("--camera", help="camera index, video file or image sequence (real robot)")
    p.add_argument("--wheels", help="serial port of the $IRODO wheel-speed lines (real robot)")
    p.add_argument("--wheels-baud", type=int, default=115200, help="its baud rate")
    p.add_argument("--sensor", type=Path, help="the camera's calibrated cam0/sensor.yaml")
    p.add_argument("--wheel-base", type=float, help="metres between the wheels (real robot)")
    p.add_argument("--max-speed", type=float, default=1.0, help="m/s (real robot)")
    p.add_argument("--light", action="store_true", help="spot-level simulation (no rendering)")
    p.add_argument("--scenario", default="demo", help="the site's scenario (default demo)")
    p.add_argument("--seed", type=int, help="the site's seed (as `irloc serve --seed`)")
    p.add_argument("--robot", help="which robot of the scenario (default: --name if it is one)")
    p.add_argument(
        "--floor",
        help="the floor it starts on (default: the site's default floor; --sim: "
        "the scenario robot's); the site tells it its floor when it changes floors",
    )
    p.add_argument("--count", type=int, default=1, help="robots in this process (NAME-000...)")
    p.add_argument("--camera-rate", type=float, help="the simulated camera's frames/s")
    p.add_argument("--odometry-rate", type=float, help="the simulated wheel samples/s")
    p.add_argument(
        "--start-known", action="store_true", help="the robot starts on its dock: a prior pose"
    )
    p.add_argument("--pose-rate", type=float, default=10.0, help="pose messages/s (0: all)")
    p.add_argument("--visualization-rate", type=float, default=1.0, help="VDA 5050 msgs/s")
    p.add_argument("--hold", type=float, help="reorder hold for LED states, s (0.03; --ros2: 0.1)")
    p.add_argument("--ros2", action="store_true", help="inputs and outputs on ROS 2 (DDS)")
    p.add_argument("--ros2-namespace", help="the robot's ROS 2 namespace (default none)")
    p.add_argument(
        "--ros2-param",
        action="append",
        metavar="KEY=VALUE",
        help="a ROS 2 setting (topic, frame, QoS; docs/ros2.md), repeatable",
    )
    p.add_argument(
        "--clock-skew", type=float, default=0.0, help="add this to the wall clock, s (tests)"
    )
    p.add_argument(
        "--truth-csv", type=Path, help="write each pose with the simulated truth (tests)"
    )
    p.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])
    return p


def with_rates(scenario: Scenario, camera_hz: float | None, odometry_hz: float | None) -> Scenario:
    """The scenario with its robots' camera and odometry rates changed (the same world)."""
    if camera_hz is not None and not 1 <= camera_hz <= 120:
        raise ValueError(f"--camera-rate must be in [1, 120] frames/s, got {camera_hz}")
    if odometry_hz is not None and not 10 <= odometry_hz <= 1000:
        raise ValueError(f"--odometry-rate must be in [10, 1000] samples/s, got {odometry_hz}")
    robots = []
    for r in scenario.robots:
        if camera_hz is not None:
            r = dataclasses.replace(r, camera=dataclasses.replace(r.camera, rate_hz=camera_hz))
        if odometry_hz is not None:
            r = dataclasses.replace(r, odometry_rate_hz=odometry_hz)
        robots.append(r)
    return dataclasses.replace(scenario, robots=tuple(robots))


def hardware_core(args: argparse.Namespace) -> AgentCore:
    """The agent of a real robot: `--camera` and/or `--wheels`, `--sensor`, `--wheel-base`."""
    import yaml

    from agent.hardware import HardwareSource
    from localizer.camera import camera_from_sensor

    if args.camera is None and args.wheels is None:
        raise ValueError("give --sim, or a real robot's --camera DEV and --wheels PORT")
    if args.sensor is None or args.wheel_base is None:
        raise ValueError("a real robot needs --sensor cam0/sensor.yaml and --wheel-base M")
    if not 0 < args.wheel_base <= 10 or not 0 < args.max_speed <= 20:
        raise ValueError("--wheel-base must be in (0, 10] m and --max-speed in (0, 20] m/s")
    try:
        sensor = yaml.safe_load(args.sensor.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"--sensor {args.sensor}: {exc}") from None
    camera = camera_from_sensor(sensor, source=str(args.sensor))
    source = HardwareSource(
        camera,
        RobotGeometry(args.wheel_base, args.max_speed),
        device=args.camera,
        wheels=args.wheels,
        baud=args.wheels_baud,
    )
    config = AgentConfig(
        name=check_name("--name", args.name),
        manufacturer=check_name("--manufacturer", args.manufacturer),
        source="camera",
        reorder_hold_s=0.03 if args.hold is None else args.hold,
        pose_rate_hz=args.pose_rate,
        visualization_rate_hz=args.visualization_rate,
        floor=args.floor and check_name("--floor", args.floor),
    )
    return AgentCore(config, source, TimeBase(round(args.clock_skew * 1e9)))


def build_cores(args: argparse.Namespace) -> list[AgentCore]:
    """One `AgentCore` per robot of this process; ValueError names a bad argument."""
    from sim.scenario import load_scenario

    if not args.sim:
        return [hardware_core(args)]
    if args.count < 1:
        raise ValueError(f"--count must be >= 1, got {args.count}")
    scenario = load_scenario(args.scenario)
    scenario = with_rates(scenario, args.camera_rate, args.odometry_rate)
    robots = [r.name for r in scenario.robots]
    names = [args.name] if args.count == 1 else [f"{args.name}-{i:03d}" for i in range(args.count)]
    cores = []
    for i, name in enumerate(names):
        check_name("--name", name)
        robot = args.robot or (name if name in robots else robots[i % len(robots)])
        source = SimRobotSource(scenario, robot, seed=args.seed, light=args.light)
        config = AgentConfig(
            name=name,
            manufacturer=check_name("--manufacturer", args.manufacturer),
            source="sim-light" if args.light else "sim",
            reorder_hold_s=0.03 if args.hold is None else args.hold,
            pose_rate_hz=args.pose_rate,
            visualization_rate_hz=args.visualization_rate,
            start_known=args.start_known,
            floor=check_name("--floor", args.floor or source.start_floor),
        )
        truth = None
        if args.truth_csv is not None:
            path = args.truth_csv if args.count == 1 else args.truth_csv.with_suffix(f".{i}.csv")
            truth = path.open("w", encoding="utf-8")
        timebase = TimeBase(round(args.clock_skew * 1e9))
        cores.append(AgentCore(config, source, timebase, truth_log=truth))
    return cores


async def _run(runtime: AgentRuntime, extra: Sequence[Startable] = ()) -> None:
    sources: list[Startable] = [
        link.core.source for link in runtime.links if isinstance(link.core.source, HardwareSource)
    ]
    sources += extra
    for s in sources:
        s.start()
    try:
        await _until_signal(runtime)
    finally:
        for s in sources:
            s.stop()


async def _until_signal(runtime: AgentRuntime) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError):
            loop.add_signal_handler(sig, stop.set)
    await runtime.run(stop)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(
        level=args.log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    try:
        broker = parse_broker_url(
            args.mqtt,
            password_file=args.mqtt_password_file,
            ca_file=args.mqtt_ca,
            cert_file=args.mqtt_cert,
            key_file=args.mqtt_key,
        )
        check_name("--site", args.site)
        ros2_robots = []
        if args.ros2:
            from agent.ros2_agent import build_ros2

            scenario = None
            if args.sim:
                from sim.scenario import load_scenario

                scenario = load_scenario(args.scenario)
                scenario = with_rates(scenario, args.camera_rate, args.odometry_rate)
            ros2_robots = build_ros2(args, scenario)
        cores = [r.core for r in ros2_robots] if args.ros2 else build_cores(args)
    except (ValueError, TimeoutError) as exc:
        print(f"irloc agent: {exc}", file=sys.stderr)
        return 2
    names = ", ".join(c.config.name for c in cores[:3]) + (" ..." if len(cores) > 3 else "")
    print(f"irloc agent: {names} on site {args.site!r} via {broker}", flush=True)
    # the sensor thread localizes while the network loop publishes: hand the interpreter over
    # more often than every 5 ms, so that a pose leaves soon after it is computed
    sys.setswitchinterval(0.001)
    first = args.connect_timeout if args.connect_timeout > 0 else None
    runtime = AgentRuntime(broker, args.site, cores, first_connect_s=first)
    asyncio.run(_run(runtime, ros2_robots))
    if runtime.failed is not None:
        print(f"irloc agent: {runtime.failed}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
