"""One simulated robot of a scenario, simulated on the agent: its odometry, and either
rendered frames (`light=False`, what a camera would give) or, in the light mode, the spots a
detection would find (`sim.spot_view.observe_spots`, the virtual site's spot-level camera: no
rendering and no spot detection, so a hundred agents fit on one machine).

The site's LEDs are switched by the site server's radio; the agent hears of each confirmed
state over MQTT and switches its copy of the world's LEDs at the state's own time
(`apply_leds`), so each frame shows the LEDs as they were when it was taken. The agent steps
this source a little behind real time (`agent.reorder`), so that every LED state of a frame's
time has arrived before the frame is made.
"""

from __future__ import annotations

from collections.abc import Iterable

from localizer.camera import CameraModel
from localizer.events import Event, FrameObserved, OdometryMeasured, SpotsObserved
from localizer.robot import RobotGeometry
from sim.build import build_robot, build_world, seed_generators
from sim.robot import FloorArrival, FramePose
from sim.scenario import Scenario
from sim.spot_view import observe_spots
from sim.virtual_site import render_view
from sim.world import IN_LIFT


class SimRobotSource:
    """Robot `robot` of `scenario` (the world as the site server builds it from the same
    scenario and seed, so the map the server publishes is this world's survey).

    Args:
        scenario: the site's scenario.
        robot: which of its robots this agent is.
        seed: the site's seed (`irloc serve --seed`).
        light: spot-level simulation instead of rendered frames (`sim.spot_view`, the
            virtual site's spot-level camera).
    """

    def __init__(
        self,
        scenario: Scenario,
        robot: str,
        *,
        seed: int | None = None,
        light: bool = False,
    ) -> None:
        names = [r.name for r in scenario.robots]
        if robot not in names:
            raise ValueError(f"robot {robot!r} is not in scenario {scenario.name!r}: {names}")
        index = names.index(robot)
        gens = seed_generators(scenario.seed if seed is None else seed, 3 + len(names))
        self.scenario = scenario
        self.world = build_world(scenario, gens[0])
        self.rig = build_robot(scenario.robots[index], scenario, gens[3 + index], index=index)
        self.light = light
        self._rng = gens[2]
        self._t0_ns: int | None = None
        self._t_local_ns = 0
        self._led_t_local_ns = 0
        self.world.led_clock_ns = lambda: self._led_t_local_ns
        self.truth: dict[int, tuple[float, float, float]] = {}
        self.truth_history = 300

    @property
    def camera(self) -> CameraModel:
        """The nominal (calibrated) camera: what the localizer is told."""
        return self.rig.camera_nominal

    @property
    def geometry(self) -> RobotGeometry:
        return self.rig.geometry

    @property
    def start_pose(self) -> tuple[float, float, float]:
        """Where the robot starts (x, y, theta; metres, radians): its dock."""
        return self.rig.spec.start

    @property
    def start_floor(self) -> str:
        """The floor the robot starts on (its scenario's)."""
        return self.rig.spec.floor

    def true_pose_at(self, t_ns: int) -> tuple[float, float, float] | None:
        """The true planar pose when the frame stamped `t_ns` was taken (recent frames)."""
        return self.truth.get(t_ns)

    def apply_leds(self, t_ns: int, lit: Iterable[int] | None) -> None:
        """The site's LEDs from `t_ns` (the agent's clock) on: exactly `lit` (None: all)."""
        lit_set = None if lit is None else set(lit)
        self._led_t_local_ns = max(0, t_ns - (self._t0_ns if self._t0_ns is not None else t_ns))
        for lm in self.world.landmarks.values():
            if lm.reachable:
                self.world.set_led(lm.id, lit_set is None or lm.id in lit_set)

    def complete_until(self, t_ns: int, max_wait_ns: int) -> int:
        """A simulated robot's samples are rendered when stepped: never behind."""
        return t_ns

    def step(self, t_ns: int) -> list[Event]:
        """Drive to `t_ns` (the agent's clock); the samples due, in time order."""
        if self._t0_ns is None:
            self._t0_ns = t_ns
            self.world.advance(0)
            return []
        local = t_ns - self._t0_ns
        if local <= self._t_local_ns:
            return []
        out: list[Event] = []
        for item in self.rig.robot.advance_to(local):
            t_out = item.t_ns + self._t0_ns
            if isinstance(item, OdometryMeasured):
                out.append(OdometryMeasured(t_out, item.v_left, item.v_right))
                continue
            if isinstance(item, FloorArrival):  # its fleet manager tells the site, not the agent
                continue
            self.world.advance(item.t_ns)
            out.append(self._frame(item, t_out))
            self.truth[t_out] = item.pose
            if len(self.truth) > self.truth_history:
                del self.truth[next(iter(self.truth))]
        self.world.advance(local)
        self._t_local_ns = local
        return out

    def _frame(self, item: FramePose, t_ns: int) -> FrameObserved | SpotsObserved:
        cam = self.rig.camera_true
        on = IN_LIFT if item.in_lift else item.floor  # the ceiling of its floor, none in the lift
        if self.light:
            return observe_spots(
                self.world,
                cam,
                item.T_world_body,
                t_ns,
                self._rng,
                self.scenario.render,
                led_t_ns=item.t_ns,
                floor=on,
            )
        image = render_view(
            self.world,
            cam,
            item.T_world_body,
            self._rng,
            self.scenario.render,
            led_t_ns=item.t_ns,
            floor=on,
        )
        return FrameObserved(t_ns, image)
