"""The robot part of a scenario file: start pose, geometry, odometry errors, camera and route,
validated field by field (errors name the file and the field's path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sim.cameras import CALIBRATION_LEVELS, LENSES, CalibrationError, Lens
from sim.fields import Node
from sim.imu import ImuSpec
from sim.routes import (
    Drive,
    DriveLimits,
    Goto,
    Kidnap,
    Lift,
    Route,
    Step,
    TurnTo,
    Wait,
    heading_sweep,
)


@dataclass(frozen=True)
class CameraSpec:
    """A robot's upward camera: lens, mounting, rate, losses, calibration error.

    `calibration_error`: True draws a good calibration's residual (`perturbed_camera`),
    False none, a `CalibrationError` that (`miscalibrated_camera`).
    """

    lens: Lens
    yaw_rad: float = 0.0
    offset_xy_m: tuple[float, float] = (0.0, 0.0)
    height_m: float = 0.3
    tilt_xy_rad: tuple[float, float] = (0.0, 0.0)
    rate_hz: float = 30.0
    drop_rate: float = 0.0
    calibration_error: bool | CalibrationError = True


@dataclass(frozen=True)
class RobotSpec:
    """One robot: start pose (x, y, theta rad), geometry, odometry errors, camera, route."""

    name: str
    start: tuple[float, float, float]
    wheel_base_m: float
    max_speed_mps: float
    wheel_radius_error: tuple[float, float]
    wheel_base_error: float
    odometry_rate_hz: float
    odometry_noise_rel: float
    camera: CameraSpec
    route: Route
    limits: DriveLimits = field(default_factory=DriveLimits)
    odometry_recorded: bool = True  # False: no odom0/data.csv (a robot without odometry)
    imu: ImuSpec | None = None  # an IMU, recorded as imu0/data.csv
    start_pose_radius_m: float | None = None  # write start_pose.yaml within this of the start
    floor: str = "0"


def route_from_node(n: Node, max_speed: float, start_theta: float) -> Route:
    n.mapping(("loop", "speed_mps", "waypoints", "dwell_s", "sweep_deg", "sweep_dwell_s", "steps"))
    speed = n.number("speed_mps", min(0.5, max_speed), low=0.01, high=max_speed)
    steps: list[Step] = []
    if n.has("waypoints"):
        dwell = n.number("dwell_s", 0.0, low=0)
        sweep = math.radians(n.number("sweep_deg", 0.0, low=0, high=180))
        sweep_dwell = n.number("sweep_dwell_s", 0.5, low=0)
        for p in n.child("waypoints").items():
            x, y = p.vector(2, "[x, y]")
            steps.append(Goto(x, y, speed))
            if dwell > 0:
                steps.append(Wait(dwell))
            if sweep > 0:
                steps += [TurnTo(start_theta), *heading_sweep(start_theta, sweep, sweep_dwell)]
    for s in n.child("steps").items():
        s.mapping(("goto", "wait", "turn_to_deg", "sweep", "drive", "kidnap", "lift"))
        if s.has("goto"):
            x, y = s.child("goto").vector(2, "[x, y]")
            steps.append(Goto(x, y, speed))
        elif s.has("wait"):
            steps.append(Wait(s.number("wait", low=0)))
        elif s.has("turn_to_deg"):
            steps.append(TurnTo(math.radians(s.number("turn_to_deg"))))
        elif s.has("sweep"):
            w = s.child("sweep").mapping(("step_deg", "dwell_s", "from_deg"))
            start = math.radians(w.number("from_deg", math.degrees(start_theta)))
            steps += [TurnTo(start)]
            steps += heading_sweep(
                start,
                math.radians(w.number("step_deg", low=1, high=180)),
                w.number("dwell_s", 0.5, low=0),
            )
        elif s.has("lift"):
            lift = s.child("lift").mapping(("floor", "ride_s", "announce"))
            steps.append(
                Lift(
                    lift.string("floor"),
                    lift.number("ride_s", 8.0, low=0.5, high=600.0),
                    lift.boolean("announce", True),
                )
            )
        elif s.has("kidnap"):
            k = s.child("kidnap").mapping(("to", "carry_s", "lift_m"))
            x, y, deg = k.child_vector("to", 3, "[x, y, theta_deg]")
            steps.append(
                Kidnap(
                    x,
                    y,
                    math.radians(deg),
                    k.number("carry_s", 2.0, low=0.1, high=60.0),
                    k.number("lift_m", 0.3, low=0.0, high=1.5),
                )
            )
        else:
            d = s.child("drive", required=True).mapping(("seconds", "v_mps", "omega_deg_s"))
            steps.append(
                Drive(
                    d.number("seconds", low=0),
                    d.number("v_mps", low=-max_speed, high=max_speed),
                    math.radians(d.number("omega_deg_s", 0.0)),
                )
            )
    return Route(tuple(steps), n.boolean("loop", False))


def calibration_from_node(n: Node) -> bool | CalibrationError:
    """`calibration_error`: true / false, a level name, or a mapping of bounds."""
    v = n.value
    if v is None:
        return True
    if isinstance(v, bool):
        return v
    if isinstance(v, str):
        if v not in CALIBRATION_LEVELS:
            raise n.error(f"expected true, false, one of {list(CALIBRATION_LEVELS)} or a mapping")
        return CALIBRATION_LEVELS[v]
    n.mapping(("focal_rel", "principal_px", "distortion_rel", "mount_deg", "mount_m"))
    return CalibrationError(
        focal_rel=n.number("focal_rel", 0.0, low=0, high=0.2),
        principal_px=n.number("principal_px", 0.0, low=0, high=50),
        distortion_rel=n.number("distortion_rel", 0.0, low=0, high=0.9),
        mount_rad=math.radians(n.number("mount_deg", 0.0, low=0, high=10)),
        mount_m=n.number("mount_m", 0.0, low=0, high=0.5),
    )


def limits_from_node(n: Node) -> DriveLimits:
    """`limits`: the controller's fastest turn and acceleration (defaults: `DriveLimits`)."""
    d = DriveLimits()
    n.mapping(
        ("max_turn_rate_deg_s", "accel_mps2", "distance_gain", "turn_accel_deg_s2", "brake_mps2")
    )
    turn_accel = (
        n.number("turn_accel_deg_s2", 0.0, low=0, high=1e5) if n.has("turn_accel_deg_s2") else None
    )
    return DriveLimits(
        angular_accel_radps2=None if turn_accel is None else math.radians(turn_accel),
        brake_mps2=n.number("brake_mps2", 1.0, low=0.05, high=1000)
        if n.has("brake_mps2")
        else None,
        max_omega_radps=math.radians(
            n.number("max_turn_rate_deg_s", math.degrees(d.max_omega_radps), low=1, high=720)
        ),
        accel_mps2=n.number("accel_mps2", d.accel_mps2, low=0.05, high=1000),
        distance_gain=n.number("distance_gain", d.distance_gain, low=0.1, high=1000),
    )


def robot_from_node(n: Node, default_lens: Lens) -> RobotSpec:
    n.mapping(
        (
            "name",
            "start",
            "wheel_base_m",
            "max_speed_mps",
            "wheel_radius_error",
            "wheel_base_error",
            "odometry",
            "camera",
            "route",
            "limits",
            "imu",
            "start_pose",
            "floor",
        )
    )
    sx, sy, sdeg = n.child_vector("start", 3, "[x, y, theta_deg]")
    max_speed = n.number("max_speed_mps", 1.0, low=0.05, high=5)
    odo = n.child("odometry", {}).mapping(("rate_hz", "noise_rel", "recorded"))
    imu = None
    if n.has("imu"):
        i = n.child("imu", {}).mapping(("gyro_noise_rad_s", "gyro_bias_rad_s", "accel_noise_m_s2"))
        d = ImuSpec()
        imu = ImuSpec(
            gyro_noise_rad_s=i.number("gyro_noise_rad_s", d.gyro_noise_rad_s, low=0, high=1),
            gyro_bias_rad_s=i.number("gyro_bias_rad_s", d.gyro_bias_rad_s, low=0, high=1),
            accel_noise_m_s2=i.number("accel_noise_m_s2", d.accel_noise_m_s2, low=0, high=10),
        )
    start_radius = None
    if n.has("start_pose"):
        start_radius = (
            n.child("start_pose").mapping(("radius_m",)).number("radius_m", 0.3, low=0.01, high=50)
        )
    cam = n.child("camera", {}).mapping(
        (
            "lens",
            "yaw_deg",
            "offset_m",
            "height_m",
            "tilt_deg",
            "rate_hz",
            "drop_rate",
            "calibration_error",
        )
    )
    tilt = cam.child_vector("tilt_deg", 2, "[about x, about y] degrees", (0.0, 0.0))
    camera = CameraSpec(
        lens=cam.string("lens", default_lens, choices=LENSES),  # type: ignore[arg-type]
        yaw_rad=math.radians(cam.number("yaw_deg", 0.0)),
        offset_xy_m=cam.child_vector("offset_m", 2, "[x, y] metres", (0.0, 0.0)),  # type: ignore[arg-type]
        height_m=cam.number("height_m", 0.3, low=0, high=2),
        tilt_xy_rad=(math.radians(tilt[0]), math.radians(tilt[1])),
        rate_hz=cam.number("rate_hz", 30.0, low=1, high=120),
        drop_rate=cam.number("drop_rate", 0.0, low=0, high=0.9),
        calibration_error=calibration_from_node(cam.child("calibration_error")),
    )
    wre = n.child_vector("wheel_radius_error", 2, "[left, right] relative errors", (0.0, 0.0))
    return RobotSpec(
        name=n.string("name"),
        start=(sx, sy, math.radians(sdeg)),
        wheel_base_m=n.number("wheel_base_m", 0.36, low=0.05, high=3),
        max_speed_mps=max_speed,
        wheel_radius_error=wre,  # type: ignore[arg-type]
        wheel_base_error=n.number("wheel_base_error", 0.0, low=-0.2, high=0.2),
        odometry_rate_hz=odo.number("rate_hz", 100.0, low=10, high=1000),
        odometry_noise_rel=odo.number("noise_rel", 0.01, low=0, high=0.5),
        camera=camera,
        route=route_from_node(n.child("route", required=True), max_speed, math.radians(sdeg)),
        limits=limits_from_node(n.child("limits", {})),
        odometry_recorded=odo.boolean("recorded", True),
        imu=imu,
        start_pose_radius_m=start_radius,
        floor=n.string("floor", "0"),
    )
