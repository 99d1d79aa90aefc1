"""`irloc agent --ros2`: the on-robot agent with its inputs and outputs on ROS 2.

The same `AgentCore` (localizer, MQTT link to the site for the map and the LED switching)
takes its sensor events from a `ros2.source.Ros2Source` (the robot's image, camera_info,
odometry, `/tf` and `/initialpose`) and tells a `ros2.outputs.Ros2Outputs` of every map and
pose (`/irloc/pose`, `map -> odom` on `/tf`, `/diagnostics`, landmark markers). With `--sim`
each robot of the scenario also gets a simulated ROS 2 driver (`agent.ros2_driver`) in this
process: the whole chain on one machine, as `irloc serve --ros2` runs it.
"""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path

from agent.core import AgentConfig, AgentCore
from agent.ros2_driver import SimRos2Driver
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.topics import check_name
from localizer.camera import CameraModel, camera_from_sensor
from localizer.robot import RobotGeometry
from ros2.outputs import Ros2Outputs
from ros2.settings import Ros2Settings
from ros2.source import Ros2Source
from ros2.transport import Ros2Participant
from sim.scenario import Scenario

log = logging.getLogger(__name__)
DEFAULT_HOLD_S = 0.1
"""Reorder hold of a ROS 2 agent: above a camera driver's publication delay and DDS's."""


@dataclass
class Ros2Robot:
    """One robot of a ROS 2 agent process."""

    core: AgentCore
    source: Ros2Source
    outputs: Ros2Outputs
    driver: SimRos2Driver | None = None

    def start(self) -> None:
        self.outputs.start()
        if self.driver is not None:
            self.driver.start()

    def stop(self) -> None:
        if self.driver is not None:
            self.driver.stop()
        self.outputs.stop()


def load_sensor(path: Path) -> CameraModel:
    import yaml

    try:
        sensor = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"--sensor {path}: {exc}") from None
    return camera_from_sensor(sensor, source=str(path))


def ros2_robot(
    node: Ros2Participant,
    config: AgentConfig,
    settings: Ros2Settings,
    geometry: RobotGeometry,
    *,
    camera: CameraModel | None,
    driver_source: SimRobotSource | None = None,
    camera_timeout_s: float = 10.0,
) -> Ros2Robot:
    """An agent core on ROS 2 topics (and its simulated driver when `driver_source`)."""
    source = Ros2Source(node, settings, geometry, camera=camera, name=config.name)
    driver = None
    if driver_source is not None:
        driver = SimRos2Driver(node, driver_source, settings)
        source.led_sink = driver.apply_leds
    outputs = Ros2Outputs(
        node, settings, source.health, source.odom_base, source.ros_stamp, name=config.name
    )
    if camera is None and driver is None:
        source.wait_for_camera(camera_timeout_s)
    core = AgentCore(config, source, TimeBase())
    core.observers.append(outputs)
    return Ros2Robot(core, source, outputs, driver)


def build_ros2(args: argparse.Namespace, scenario: Scenario | None) -> list[Ros2Robot]:
    """The robots of `irloc agent --ros2 ...` (`scenario`: the site's, with `--sim`;
    ValueError names a bad argument)."""
    node = Ros2Participant()
    base = Ros2Settings(namespace=args.ros2_namespace or "").with_overrides(args.ros2_param or [])
    hold = DEFAULT_HOLD_S if args.hold is None else args.hold
    manufacturer = check_name("--manufacturer", args.manufacturer)
    if scenario is None:
        if args.wheel_base is None or not 0 < args.wheel_base <= 10:
            raise ValueError("--ros2 needs the robot's --wheel-base M (in (0, 10])")
        camera = load_sensor(args.sensor) if args.sensor is not None else None
        config = AgentConfig(
            name=check_name("--name", args.name), manufacturer=manufacturer, source="camera",
            reorder_hold_s=hold, pose_rate_hz=args.pose_rate,
            visualization_rate_hz=args.visualization_rate,
        )  # fmt: skip
        geometry = RobotGeometry(args.wheel_base, args.max_speed)
        return [ros2_robot(node, config, base, geometry, camera=camera)]
    names = [r.name for r in scenario.robots]
    wanted = names if args.name == "all" else [args.name]
    if args.name == "all" and args.ros2_namespace is not None:
        raise ValueError("--name all puts each robot under its own name: no --ros2-namespace")
    robots = []
    for name in wanted:
        check_name("--name", name)
        sim_robot = args.robot or (name if name in names else names[0])
        sim = SimRobotSource(scenario, sim_robot, seed=args.seed)
        settings = base if args.name != "all" and args.ros2_namespace is not None else (
            Ros2Settings(namespace=name).with_overrides(args.ros2_param or [])
        )  # fmt: skip
        config = AgentConfig(
            name=name, manufacturer=manufacturer, source="sim", reorder_hold_s=hold,
            pose_rate_hz=args.pose_rate, visualization_rate_hz=args.visualization_rate,
            start_known=args.start_known,
        )  # fmt: skip
        robots.append(ros2_robot(
            node, config, settings, sim.geometry, camera=sim.camera, driver_source=sim
        ))  # fmt: skip
    return robots
