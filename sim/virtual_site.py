"""The virtual site, clocked from outside: `irloc serve` steps it from its clock thread and
feeds the frames and odometry to the robots' localizers, while the RF gateway drives the
site's `SimRadio`. Nothing here sleeps or reads a clock.

Time: the first `step(t_ns)` fixes the site's start; every sample carries the caller's clock.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from lighting.energy import RadioSleep
from localizer.camera import CameraModel
from localizer.events import FrameObserved, OdometryMeasured, SpotsObserved
from localizer.robot import RobotGeometry
from localizer.types import FloatArray, ImageU8
from sim.build import RobotRig, build_robot, build_world, seed_generators
from sim.radio import SimRadio
from sim.render import RenderConfig, render_frame
from sim.robot import FloorArrival, FramePose
from sim.scenario import FloorSpec, Scenario, load_scenario
from sim.spot_view import observe_spots
from sim.world import IN_LIFT, World


def render_view(
    world: World,
    camera: CameraModel,
    T_world_body: FloatArray,
    rng: np.random.Generator,
    config: RenderConfig,
    *,
    led_t_ns: int | None = None,
    floor: str | None = None,
) -> ImageU8:
    """The frame a (true) camera sees from a body pose (4, 4) in the world as it is now (with
    the LEDs as they were at world time `led_t_ns` when given), on `floor`
    (`World.point_sources`; None: every landmark)."""
    p_cam = (T_world_body @ camera.T_body_camera)[:3, 3]
    sources, intensities = world.point_sources(p_cam, t_ns=led_t_ns, floor=floor)
    return render_frame(
        camera,
        T_world_body,
        sources,
        intensities,
        rng=rng,
        config=config,
        extended=world.extended,
    )


@dataclass(frozen=True, eq=False)
class SensorSample:
    """A frame or an odometry sample of the robot `robot`."""

    robot: str
    event: FrameObserved | SpotsObserved | OdometryMeasured | FloorArrival


class VirtualSite:
    """The simulated site: world, radio and robots, advanced by `step`.

    Args:
        scenario: a `Scenario` or a built-in name / scenario file path.
        seed: overrides the scenario's seed.
        max_frame_lag_s: frames older than this at a `step` are dropped (the caller fell
            behind); the robots still move through that time.
        radio_sleep: the landmarks' radios sleep in cycles (`SimRadio`); None: awake.
        observe: "frames" renders every frame; "spots" reports each frame's spots directly
            (`sim.spot_view`, for long simulated shifts).
    """

    def __init__(
        self,
        scenario: Scenario | str,
        *,
        seed: int | None = None,
        max_frame_lag_s: float = 0.2,
        clock_ns: Callable[[], int] | None = None,
        radio_sleep: RadioSleep | None = None,
        observe: Literal["frames", "spots"] = "frames",
    ) -> None:
        self.scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
        sc = self.scenario
        gens = seed_generators(sc.seed if seed is None else seed, 3 + len(sc.robots))
        self.world: World = build_world(sc, gens[0])
        self.radio = SimRadio(
            self.world,
            rng=gens[1],
            latency_s=sc.radio_latency_s,
            loss=sc.radio_loss,
            timeout_s=max(0.3, 2.0 * sc.radio_latency_s[1]),
            sleep=radio_sleep,
        )
        self.observe = observe
        self._render_rng = gens[2]
        self._rigs: dict[str, RobotRig] = {
            spec.name: build_robot(spec, sc, gens[3 + i], index=i)
            for i, spec in enumerate(sc.robots)
        }
        self._t0_ns: int | None = None
        self._t_local_ns = 0
        self._max_lag_ns = round(max_frame_lag_s * 1e9)
        self.truth_history = 1000
        self._frame_truth: dict[str, dict[int, tuple[float, float, float]]] = {
            name: {} for name in self._rigs
        }
        self._floor_truth: dict[str, dict[int, str]] = {name: {} for name in self._rigs}
        if clock_ns is not None:
            # The radio switches LEDs between steps: log each switch at its own time, so
            # that a frame shows the LEDs as they were at the frame's time.
            self.world.led_clock_ns = lambda: self._site_time_ns(clock_ns())

    def _site_time_ns(self, t_ns: int) -> int:
        """A time of the caller's clock on the site's time (0 before the first step)."""
        return 0 if self._t0_ns is None else t_ns - self._t0_ns

    @property
    def robot_names(self) -> list[str]:
        return list(self._rigs)

    def rig(self, name: str) -> RobotRig:
        """A robot's simulation internals; KeyError names an unknown robot."""
        try:
            return self._rigs[name]
        except KeyError:
            raise KeyError(f"unknown robot {name!r}; robots: {self.robot_names}") from None

    def camera(self, name: str) -> CameraModel:
        """The robot's nominal (calibrated) camera, as its localizer should use it."""
        return self.rig(name).camera_nominal

    def robot_geometry(self, name: str) -> RobotGeometry:
        return self.rig(name).geometry

    def landmark_records(self) -> list[dict[str, object]]:
        """The surveyed map with each landmark's `radio` address (map.json's landmarks)."""
        return self.world.landmark_records()

    def true_pose(self, name: str) -> tuple[float, float, float]:
        """The robot's true (x, y, theta) at the last stepped time."""
        return self.rig(name).robot.pose_at(self._t_local_ns)

    def planned_route(self, name: str, count: int = 4) -> tuple[tuple[float, float], ...]:
        """The next points of the robot's route, (x, y) metres (as its fleet manager would
        know them; empty when it is not following waypoints)."""
        return self.rig(name).robot.follower.upcoming(count)

    def true_pose_at(self, name: str, t_ns: int) -> tuple[float, float, float] | None:
        """The robot's true (x, y, theta) when it took its frame stamped `t_ns` (one of the
        last `truth_history` frames), or None."""
        return self._frame_truth[name].get(t_ns)

    def true_floor_at(self, name: str, t_ns: int) -> str | None:
        """The floor robot `name` was on when it took its frame stamped `t_ns`
        (`sim.world.IN_LIFT` in the lift; one of the last `truth_history` frames), or None."""
        return self._floor_truth[name].get(t_ns)

    def true_floor(self, name: str) -> str:
        """The floor the robot is on (while in the lift: the one it boarded on)."""
        return self.rig(name).robot.floor

    @property
    def floors(self) -> tuple[FloorSpec, ...]:
        """The building's floors (one, "0", for a scenario that names none)."""
        return self.scenario.floors

    def render(
        self,
        name: str,
        T_world_body: FloatArray,
        *,
        t_ns: int | None = None,
        floor: str | None = None,
    ) -> ImageU8:
        """The frame robot `name`'s true camera sees from a body pose, with the world now
        (with the LEDs as they were at site time `t_ns` when given), on `floor` (None: the
        robot's floor now; `sim.world.IN_LIFT`: in the lift cabin)."""
        on = self.true_floor(name) if floor is None else floor
        return render_view(
            self.world,
            self.rig(name).camera_true,
            T_world_body,
            self._render_rng,
            self.scenario.render,
            led_t_ns=t_ns,
            floor=on,
        )

    def step(self, t_ns: int) -> list[SensorSample]:
        """Advance robots, batteries and people to `t_ns`; the samples due, in time order.

        The first call only fixes the start time. Frames are rendered with the LEDs lit at
        their own time when the site has a clock (`clock_ns`), else at the moment of the
        call.
        """
        if self._t0_ns is None:
            self._t0_ns = t_ns
            self.world.advance(0)
            return []
        local = t_ns - self._t0_ns
        if local <= self._t_local_ns:
            return []
        due: list[tuple[int, int, str, OdometryMeasured | FramePose | FloorArrival]] = []
        for name, rig in self._rigs.items():
            for item in rig.robot.advance_to(local):
                kind = 0 if isinstance(item, OdometryMeasured | FloorArrival) else 1
                due.append((item.t_ns, kind, name, item))
        due.sort(key=lambda d: (d[0], d[1]))
        out: list[SensorSample] = []
        for t_local, _, name, item in due:
            t_out = t_local + self._t0_ns
            if isinstance(item, OdometryMeasured):
                out.append(SensorSample(name, OdometryMeasured(t_out, item.v_left, item.v_right)))
            elif isinstance(item, FloorArrival):
                arrival = FloorArrival(t_out, item.floor, item.pose, item.announce)
                out.append(SensorSample(name, arrival))
            elif local - t_local <= self._max_lag_ns:
                self.world.advance(t_local)
                truth = self._frame_truth[name]
                truth[t_out] = item.pose
                self._floor_truth[name][t_out] = IN_LIFT if item.in_lift else item.floor
                if len(truth) > self.truth_history:
                    del truth[next(iter(truth))]
                    del self._floor_truth[name][next(iter(self._floor_truth[name]))]
                on = IN_LIFT if item.in_lift else item.floor
                if self.observe == "spots":
                    cam = self.rig(name).camera_true
                    spots = observe_spots(
                        self.world,
                        cam,
                        item.T_world_body,
                        t_out,
                        self._render_rng,
                        self.scenario.render,
                        led_t_ns=t_local,
                        floor=on,
                    )
                    out.append(SensorSample(name, spots))
                    continue
                image = self.render(name, item.T_world_body, t_ns=t_local, floor=on)
                out.append(SensorSample(name, FrameObserved(t_out, image)))
        self.world.advance(local)
        self._t_local_ns = local
        return out
