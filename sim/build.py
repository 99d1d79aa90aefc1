"""Turn a scenario and its seed into the simulated site: the world (true and surveyed
landmarks, batteries, clutter), and for each robot its motion model, odometry errors, nominal
camera (as written to sensor.yaml) and true camera (with calibration error).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lighting.battery import Battery, BatteryConfig
from localizer.camera import CameraModel, T_body_camera_upward
from localizer.robot import RobotGeometry
from sim.cameras import CalibrationError, miscalibrated_camera, perturbed_camera, wide_angle_camera
from sim.render import ExtendedSource, disc_outline
from sim.robot import OdometryModel, SimRobot
from sim.robot_spec import RobotSpec
from sim.scenario import Scenario
from sim.world import Glint, Person, SimLandmark, World

ADDRESS_PREFIX = 0x0013A20041000000


def default_address(landmark_id: int) -> str:
    """The radio address of a landmark without one: 0013A2004100xxxx (16 hex digits)."""
    return f"{ADDRESS_PREFIX + landmark_id:016X}"


@dataclass(frozen=True, eq=False)
class RobotRig:
    """A simulated robot with what the localizer is told about it and what is really so."""

    spec: RobotSpec
    robot: SimRobot
    geometry: RobotGeometry
    camera_nominal: CameraModel
    camera_true: CameraModel


def build_world(scenario: Scenario, rng: np.random.Generator) -> World:
    """The world of a scenario; `rng` draws the survey errors."""
    landmarks: dict[int, SimLandmark] = {}
    panel = scenario.panels
    extended = []
    for spec in scenario.landmarks:
        p_true = np.array([spec.x, spec.y, spec.z])
        p_surveyed = p_true + rng.normal(0.0, scenario.survey_sigma_m, 3)
        passive = panel is not None  # a ceiling light: no LED to switch, no radio
        landmarks[spec.id] = SimLandmark(
            spec.id,
            p_true,
            p_surveyed,
            (spec.address or default_address(spec.id)).upper(),
            Battery(BatteryConfig(capacity_mah=spec.capacity_mah), charge=spec.charge),
            radio_dead=spec.radio_dead or passive,
            led_on=not spec.radio_dead,
            led_dead=spec.led_dead or passive,
            floor=spec.floor,
            panel_size_m=0.0 if panel is None else max(panel.width_m, panel.length_m),
            map_sigma_m=None if panel is None else panel.map_sigma_m,
        )
        if panel is not None:
            corners = panel.outline_xy(spec.x, spec.y)
            outline = np.column_stack([corners, np.full(len(corners), spec.z)])
            extended.append(ExtendedSource(outline, panel.brightness, f"panel {spec.id}"))
    for e in scenario.extended:
        if e.kind == "lamp":
            outline = disc_outline([*e.outline_xy[0], e.z], e.radius_m)
        else:
            outline = np.array([[x, y, e.z] for x, y in e.outline_xy])
        extended.append(ExtendedSource(outline, e.brightness, e.kind))
    glints = [Glint((g.x, g.y, g.z), g.intensity, g.blink_period_s) for g in scenario.glints]
    people = [Person(p.path, p.speed_mps, p.radius_m, p.height_m) for p in scenario.people]
    return World(landmarks, glints, extended, people)


def build_robot(
    spec: RobotSpec, scenario: Scenario, rng: np.random.Generator, *, index: int, t0_ns: int = 0
) -> RobotRig:
    """One robot of a scenario; `rng` draws its calibration error, noise and dropped frames."""
    mount = T_body_camera_upward(
        yaw=spec.camera.yaw_rad,
        offset_xy=spec.camera.offset_xy_m,
        height=spec.camera.height_m,
        tilt_xy=spec.camera.tilt_xy_rad,
    )
    nominal = wide_angle_camera(spec.camera.lens, T_body_camera=mount, rate_hz=spec.camera.rate_hz)
    error = spec.camera.calibration_error
    if isinstance(error, CalibrationError):
        true = miscalibrated_camera(nominal, error, rng)
    else:
        true = perturbed_camera(nominal, rng) if error else nominal
    el, er = spec.wheel_radius_error
    odometry = OdometryModel(
        rate_hz=spec.odometry_rate_hz,
        wheel_scale=(1.0 / (1.0 + el), 1.0 / (1.0 + er)),
        wheel_base_true_m=spec.wheel_base_m * (1.0 + spec.wheel_base_error),
        noise_rel=spec.odometry_noise_rel,
    )
    robot = SimRobot(
        spec.name,
        start=spec.start,
        route=spec.route,
        odometry=odometry,
        camera_rate_hz=spec.camera.rate_hz,
        frame_drop=spec.camera.drop_rate,
        bumps=scenario.bumps,
        rng=rng,
        t0_ns=t0_ns,
        frame_offset_ns=(index * 7_000_000) % round(1e9 / spec.camera.rate_hz),
        limits=spec.limits,
        slips=scenario.slips,
        floor=spec.floor,
    )
    geometry = RobotGeometry(spec.wheel_base_m, spec.max_speed_mps)
    return RobotRig(spec, robot, geometry, nominal, true)


def seed_generators(seed: int, count: int) -> list[np.random.Generator]:
    """Independent generators for the parts of a site (world, radio, renderer, robots...)."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(count)]
