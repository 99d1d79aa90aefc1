"""Scenario files: a building, its landmarks and IR clutter, and the robots driving in it.

A scenario is a plain YAML file (see `docs/sim.md` and the built-ins in `sim/scenarios/`,
which a user can copy and edit). `load_scenario` validates it field by field; every error
names the file and the field's path. Nothing random happens here: `sim.build` turns a
scenario and its seed into a world and robots.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from sim.cameras import LENSES, Lens
from sim.fields import Node
from sim.render import RenderConfig
from sim.robot import FloorBump
from sim.routes import Drive, Goto, Route, Step, TurnTo, Wait, heading_sweep

SCENARIOS: tuple[str, ...] = ("demo", "paper_testbed", "paper_floor", "dense_grid_fast", "hostile")


@dataclass(frozen=True)
class LandmarkSpec:
    """A landmark's true position (metres), battery charge (0..1), radio, and address."""

    id: int
    x: float
    y: float
    z: float
    charge: float = 1.0
    radio_dead: bool = False
    address: str | None = None
    capacity_mah: float = 2500.0


@dataclass(frozen=True)
class CameraSpec:
    """A robot's upward camera: lens, mounting, rate, losses, calibration error."""

    lens: Lens
    yaw_rad: float = 0.0
    offset_xy_m: tuple[float, float] = (0.0, 0.0)
    height_m: float = 0.3
    tilt_xy_rad: tuple[float, float] = (0.0, 0.0)
    rate_hz: float = 30.0
    drop_rate: float = 0.0
    calibration_error: bool = True


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


@dataclass(frozen=True)
class ExtendedSpec:
    """A lamp (disc) or a sunlight patch (polygon) on the ceiling."""

    kind: str
    outline_xy: tuple[tuple[float, float], ...]
    z: float
    brightness: float
    radius_m: float = 0.0


@dataclass(frozen=True)
class GlintSpec:
    x: float
    y: float
    z: float
    intensity: float
    blink_period_s: float = 0.0


@dataclass(frozen=True)
class PersonSpec:
    path: tuple[tuple[float, float], ...]
    speed_mps: float
    radius_m: float
    height_m: float


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (see `docs/sim.md` for the file format)."""

    name: str
    description: str
    seed: int
    duration_s: float
    survey_sigma_m: float
    landmarks: tuple[LandmarkSpec, ...]
    extended: tuple[ExtendedSpec, ...]
    glints: tuple[GlintSpec, ...]
    people: tuple[PersonSpec, ...]
    bumps: tuple[FloorBump, ...]
    robots: tuple[RobotSpec, ...]
    radio_latency_s: tuple[float, float]
    radio_loss: float
    render: RenderConfig

    def with_lens(self, lens: Lens) -> Scenario:
        """The same scenario with every robot's camera on `lens`."""
        robots = tuple(
            dataclasses.replace(r, camera=dataclasses.replace(r.camera, lens=lens))
            for r in self.robots
        )
        return dataclasses.replace(self, robots=robots)


_TOP = (
    "name", "description", "seed", "duration_s", "survey_sigma_m", "ceiling_height_m", "lens",
    "landmarks", "landmark_grid", "landmark_pairs", "lamps", "sunlight", "glints", "people",
    "floor_bumps", "radio", "render", "robots",
)  # fmt: skip


def _landmarks(doc: Node, ceiling: float) -> tuple[LandmarkSpec, ...]:
    out: list[LandmarkSpec] = []
    for n in doc.child("landmarks").items():
        n.mapping(("id", "x", "y", "z", "charge", "dead", "radio", "capacity_mah"))
        out.append(
            LandmarkSpec(
                n.integer("id"), n.number("x"), n.number("y"),
                n.number("z", ceiling, low=0.5), n.number("charge", 1.0, low=0, high=1),
                n.boolean("dead", False), n.string("radio", "") or None,
                n.number("capacity_mah", 2500.0, low=0.001),
            )
        )  # fmt: skip
    if doc.has("landmark_grid"):
        g = doc.child("landmark_grid").mapping(
            ("first_id", "x0", "y0", "nx", "ny", "spacing_m", "z")
        )
        first, nx, ny = g.integer("first_id"), g.integer("nx", low=1), g.integer("ny", low=1)
        x0, y0, s = g.number("x0"), g.number("y0"), g.number("spacing_m", low=0.05)
        z = g.number("z", ceiling, low=0.5)
        for j in range(ny):
            for i in range(nx):
                out.append(LandmarkSpec(first + j * nx + i, x0 + i * s, y0 + j * s, z))
    for n in doc.child("landmark_pairs").items():
        n.mapping(("first_id", "x", "y", "spacing_m", "angle_deg", "z"))
        first, x, y = n.integer("first_id"), n.number("x"), n.number("y")
        half, a = 0.5 * n.number("spacing_m", low=0.05), math.radians(n.number("angle_deg", 0.0))
        z = n.number("z", ceiling, low=0.5)
        dx, dy = half * math.cos(a), half * math.sin(a)
        out += [LandmarkSpec(first, x - dx, y - dy, z), LandmarkSpec(first + 1, x + dx, y + dy, z)]
    seen: set[int] = set()
    for lm in out:
        if lm.id in seen:
            raise doc.error(f"landmark id {lm.id} appears twice")
        seen.add(lm.id)
    if not out:
        raise doc.error("no landmarks (give landmarks, landmark_grid or landmark_pairs)")
    return tuple(out)


def _points(n: Node, key: str, minimum: int) -> tuple[tuple[float, float], ...]:
    items = n.child(key, required=True).items()
    if len(items) < minimum:
        raise n.child(key).error(f"expected at least {minimum} points [x, y]")
    return tuple(p.vector(2, "[x, y]") for p in items)  # type: ignore[misc]


def _route(n: Node, max_speed: float, start_theta: float) -> Route:
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
        s.mapping(("goto", "wait", "turn_to_deg", "sweep", "drive"))
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
            steps += heading_sweep(start, math.radians(w.number("step_deg", low=1, high=180)),
                                   w.number("dwell_s", 0.5, low=0))  # fmt: skip
        else:
            d = s.child("drive", required=True).mapping(("seconds", "v_mps", "omega_deg_s"))
            steps.append(
                Drive(d.number("seconds", low=0), d.number("v_mps", low=-max_speed, high=max_speed),
                      math.radians(d.number("omega_deg_s", 0.0)))
            )  # fmt: skip
    return Route(tuple(steps), n.boolean("loop", False))


def _robot(n: Node, default_lens: Lens) -> RobotSpec:
    n.mapping((
        "name", "start", "wheel_base_m", "max_speed_mps", "wheel_radius_error",
        "wheel_base_error", "odometry", "camera", "route",
    ))  # fmt: skip
    sx, sy, sdeg = n.child_vector("start", 3, "[x, y, theta_deg]")
    max_speed = n.number("max_speed_mps", 1.0, low=0.05, high=5)
    odo = n.child("odometry", {}).mapping(("rate_hz", "noise_rel"))
    cam = n.child("camera", {}).mapping((
        "lens", "yaw_deg", "offset_m", "height_m", "tilt_deg", "rate_hz", "drop_rate",
        "calibration_error",
    ))  # fmt: skip
    tilt = cam.child_vector("tilt_deg", 2, "[about x, about y] degrees", (0.0, 0.0))
    camera = CameraSpec(
        lens=cam.string("lens", default_lens, choices=LENSES),  # type: ignore[arg-type]
        yaw_rad=math.radians(cam.number("yaw_deg", 0.0)),
        offset_xy_m=cam.child_vector("offset_m", 2, "[x, y] metres", (0.0, 0.0)),  # type: ignore[arg-type]
        height_m=cam.number("height_m", 0.3, low=0, high=2),
        tilt_xy_rad=(math.radians(tilt[0]), math.radians(tilt[1])),
        rate_hz=cam.number("rate_hz", 30.0, low=1, high=120),
        drop_rate=cam.number("drop_rate", 0.0, low=0, high=0.9),
        calibration_error=cam.boolean("calibration_error", True),
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
        route=_route(n.child("route", required=True), max_speed, math.radians(sdeg)),
    )


def _clutter(doc: Node, ceiling: float) -> tuple[tuple[ExtendedSpec, ...], tuple[GlintSpec, ...]]:
    ext: list[ExtendedSpec] = []
    for n in doc.child("lamps").items():
        n.mapping(("x", "y", "z", "radius_m", "brightness"))
        ext.append(ExtendedSpec("lamp", ((n.number("x"), n.number("y")),), n.number("z", ceiling),
                                n.number("brightness", 800.0, low=0), n.number("radius_m", 0.1, low=0.01)))  # fmt: skip
    for n in doc.child("sunlight").items():
        n.mapping(("polygon", "z", "brightness"))
        ext.append(ExtendedSpec("sunlight", _points(n, "polygon", 3), n.number("z", ceiling),
                                n.number("brightness", 120.0, low=0)))  # fmt: skip
    glints = []
    for n in doc.child("glints").items():
        n.mapping(("x", "y", "z", "intensity", "blink_period_s"))
        glints.append(GlintSpec(n.number("x"), n.number("y"), n.number("z", ceiling),
                                n.number("intensity", 0.3, low=0), n.number("blink_period_s", 0.0, low=0)))  # fmt: skip
    return tuple(ext), tuple(glints)


def scenario_from_dict(data: object, *, source: str) -> Scenario:
    """Validate a parsed scenario document.

    Raises:
        ValueError: "SOURCE: field.path: what is wrong".
    """
    doc = Node(data, "", source).mapping(_TOP)
    ceiling = doc.number("ceiling_height_m", 2.5, low=0.5, high=20)
    lens = doc.string("lens", "fisheye", choices=LENSES)
    robots = tuple(_robot(n, lens) for n in doc.child("robots", required=True).items())  # type: ignore[arg-type]
    if not robots:
        raise doc.child("robots").error("expected at least one robot")
    if len({r.name for r in robots}) != len(robots):
        raise doc.child("robots").error("robot names must be unique")
    ext, glints = _clutter(doc, ceiling)
    people = []
    for n in doc.child("people").items():
        n.mapping(("path", "speed_mps", "radius_m", "height_m"))
        people.append(PersonSpec(_points(n, "path", 2), n.number("speed_mps", 1.0, low=0),
                                 n.number("radius_m", 0.25, low=0.05), n.number("height_m", 1.8, low=0.1)))  # fmt: skip
    bumps = []
    for n in doc.child("floor_bumps").items():
        n.mapping(("x", "y", "radius_m", "height_m"))
        bumps.append(FloorBump(n.number("x"), n.number("y"), n.number("radius_m", low=0.05),
                               n.number("height_m", low=-0.2, high=0.2)))  # fmt: skip
    radio = doc.child("radio", {}).mapping(("latency_s", "loss"))
    latency = radio.child_vector("latency_s", 2, "[min, max] seconds", (0.01, 0.04))
    render = doc.child("render", {}).mapping(
        tuple(f.name for f in dataclasses.fields(RenderConfig))
    )
    try:
        render_cfg = RenderConfig(**render.value)
    except (TypeError, ValueError) as exc:
        raise render.error(str(exc)) from None
    return Scenario(
        name=doc.string("name", Path(source).stem),
        description=doc.string("description", ""),
        seed=doc.integer("seed", 0),
        duration_s=doc.number("duration_s", 60.0, low=0.1),
        survey_sigma_m=doc.number("survey_sigma_m", 0.005, low=0, high=1),
        landmarks=_landmarks(doc, ceiling),
        extended=ext,
        glints=glints,
        people=tuple(people),
        bumps=tuple(bumps),
        robots=robots,
        radio_latency_s=(latency[0], latency[1]),
        radio_loss=radio.number("loss", 0.02, low=0, high=0.9),
        render=render_cfg,
    )


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A built-in scenario by name (`SCENARIOS`) or a scenario file by path.

    Raises:
        ValueError: unknown name, unreadable file, or invalid content (naming the field).
    """
    text_name = str(name_or_path)
    if text_name in SCENARIOS:
        source = f"{text_name}.yaml"
        text = (resources.files("sim.scenarios") / source).read_text(encoding="utf-8")
    else:
        path = Path(name_or_path)
        source = str(path)
        if not path.is_file():
            raise ValueError(
                f"{source}: no such scenario file (built-in scenarios: {', '.join(SCENARIOS)})"
            )
        text = path.read_text(encoding="utf-8")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{source}: invalid YAML: {exc}") from None
    return scenario_from_dict(data, source=source)
