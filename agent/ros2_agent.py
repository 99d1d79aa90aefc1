"""`irloc agent --ros2`: the on-robot agent with its inputs and outputs on ROS 2.

The same `AgentCore` (localizer, MQTT link to the site for the map and the LED switching)
takes its sensor events from `Ros2SensorSource`: the robot's image, camera_info and
odometry (`sensors.ros2.Ros2Source`, a frame source) and `/initialpose`; it tells a
`ros2.outputs.Ros2Outputs` of every map and pose (`/irloc/pose`, `map -> odom` on `/tf`
from the robot's own `odom -> base_link`, `/diagnostics`, landmark markers). With `--sim`
each robot of the scenario also gets a simulated ROS 2 driver (`agent.ros2_driver`) in this
process: the whole chain on one machine, as `irloc serve --ros2` runs it.
"""

from __future__ import annotations

import argparse
import logging
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from agent.core import AgentConfig, AgentCore
from agent.ros2_driver import SimRos2Driver
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.topics import check_name
from localizer.camera import CameraModel, camera_from_sensor
from localizer.events import Event, FrameObserved, RelocalizeRequested
from localizer.robot import RobotGeometry
from ros2.initialpose import InitialPoseListener
from ros2.outputs import Ros2Outputs
from ros2.settings import Ros2Settings
from ros2.transport import Ros2Participant
from sensors.event_buffer import EventBuffer
from sensors.ros2 import Ros2Source
from sim.scenario import Scenario

log = logging.getLogger(__name__)
DEFAULT_HOLD_S = 0.1
"""Reorder hold of a ROS 2 agent: above a camera driver's publication delay and DDS's."""


class Ros2SensorSource:
    """The agent's sensor source on ROS 2: the robot's camera and odometry
    (`sensors.ros2.Ros2Source`, a `FrameSource` pushing into an `EventBuffer`) and its
    `/initialpose`, taken in time order by the agent's tick. A topic that falls behind holds
    the tick back (up to the agent's `input_wait_s`); an input that arrives after the tick
    went past its time all the same is dropped and reported (fed late, it would reach the
    localizer out of order).

    Attributes:
        led_sink: where the site's LED states go (None on a real robot, whose camera sees
            the real LEDs; the simulated world of a demo driver).
    """

    def __init__(
        self, source: Ros2Source, start_pose: tuple[float, float, float] | None = None
    ) -> None:
        self.inputs = source
        self.health = source.health
        self._buffer = EventBuffer()
        self._released_ns = 0
        self._requests: list[tuple[float, float, float]] = []
        self._lock = threading.Lock()
        self.led_sink: Callable[[int, frozenset[int] | None], None] | None = None
        self.initialpose: InitialPoseListener | None = None
        self.late = 0
        self._start_pose = start_pose

    @property
    def camera(self) -> CameraModel:
        return self.inputs.camera

    @property
    def geometry(self) -> RobotGeometry:
        return self.inputs.geometry

    @property
    def start_pose(self) -> tuple[float, float, float] | None:
        """Where the robot starts, when known (a demo robot's dock; a real robot: None,
        `/initialpose` tells it)."""
        return self._start_pose

    def start(self) -> None:
        self.inputs.start(self._buffer)

    def stop(self) -> None:
        self.inputs.stop()

    def relocalize(self, near: tuple[float, float, float]) -> None:
        """Relocalize near `near` (x, y, yaw in map) at the next tick (`/initialpose`)."""
        with self._lock:
            self._requests.append(near)

    def complete_until(self, t_ns: int, max_wait_ns: int) -> int:
        """How far the image and odometry topics both delivered: a reader thread or a
        transport that stalled holds the agent back rather than having its samples dropped
        (`EventBuffer.complete_until`)."""
        return self._buffer.complete_until(t_ns, max_wait_ns)

    def step(self, t_ns: int) -> list[Event]:
        """The inputs stamped up to `t_ns` (monotonic), in time order; then the requests."""
        due: list[Event] = []
        for e in self._buffer.take_due(t_ns):
            if e.t_ns <= self._released_ns:
                self.late += 1
                kind = "image" if isinstance(e, FrameObserved) else "odom"
                self.health.report(
                    kind,
                    "warn",
                    f"arrived {(self._released_ns - e.t_ns) / 1e6:.0f} ms after the agent passed "
                    "its time (its topic was silent for longer than the agent waits, or started "
                    "after the others): dropped",
                )
                continue
            due.append(e)
        self._released_ns = max(self._released_ns, t_ns)
        with self._lock:
            requests, self._requests = self._requests, []
        return due + [RelocalizeRequested(t_ns, near) for near in requests]

    def apply_leds(self, t_ns: int, lit: Iterable[int] | None) -> None:
        """A real robot's camera sees the real LEDs: nothing to do (`led_sink`: a demo)."""
        if self.led_sink is not None:
            self.led_sink(t_ns, None if lit is None else frozenset(lit))

    def true_pose_at(self, t_ns: int) -> tuple[float, float, float] | None:
        return None

    def ros_stamp(self, t_mono_ns: int) -> int:
        return self.inputs.ros_stamp(t_mono_ns)


@dataclass
class Ros2Robot:
    """One robot of a ROS 2 agent process."""

    core: AgentCore
    source: Ros2SensorSource
    outputs: Ros2Outputs
    driver: SimRos2Driver | None = None

    def start(self) -> None:
        self.source.start()
        self.outputs.start()
        if self.driver is not None:
            self.driver.start()

    def stop(self) -> None:
        if self.driver is not None:
            self.driver.stop()
        self.outputs.stop()
        self.source.stop()


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
    inputs = Ros2Source(config.name, node, settings, geometry, camera=camera)
    source = Ros2SensorSource(
        inputs, driver_source.start_pose if driver_source is not None else None
    )
    source.initialpose = InitialPoseListener(node, settings, source.health, source.relocalize)
    driver = None
    if driver_source is not None:
        driver = SimRos2Driver(node, driver_source, settings)
        source.led_sink = driver.apply_leds
    outputs = Ros2Outputs(node, settings, source.health, source.ros_stamp, name=config.name)
    if camera is None and driver is None:
        inputs.wait_for_camera(camera_timeout_s)
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
            name=check_name("--name", args.name),
            manufacturer=manufacturer,
            source="camera",
            reorder_hold_s=hold,
            pose_rate_hz=args.pose_rate,
            visualization_rate_hz=args.visualization_rate,
            floor=args.floor and check_name("--floor", args.floor),
        )
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
        settings = (
            base
            if args.name != "all" and args.ros2_namespace is not None
            else (Ros2Settings(namespace=name).with_overrides(args.ros2_param or []))
        )
        config = AgentConfig(
            name=name,
            manufacturer=manufacturer,
            source="sim",
            reorder_hold_s=hold,
            pose_rate_hz=args.pose_rate,
            visualization_rate_hz=args.visualization_rate,
            start_known=args.start_known,
            floor=check_name("--floor", args.floor or sim.start_floor),
        )
        robots.append(
            ros2_robot(node, config, settings, sim.geometry, camera=sim.camera, driver_source=sim)
        )
    return robots
