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

import numpy as np
import yaml

from localizer.types import FloatArray
from sim.cameras import LENSES, CalibrationError, Lens
from sim.fields import Node
from sim.render import RenderConfig
from sim.robot import FloorBump, FloorTilt, SlipPatch
from sim.robot_spec import RobotSpec, robot_from_node

SCENARIOS: tuple[str, ...] = (
    "demo",
    "paper_testbed",
    "paper_floor",
    "dense_grid_fast",
    "hostile",
    "floor50",
    "two_floors",
)


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
    led_dead: bool = False
    floor: str = "0"


@dataclass(frozen=True)
class FloorSpec:
    """One floor of the building: its ID, name, level and height above level 0 (metres)."""

    id: str
    name: str
    level: int
    height_m: float


@dataclass(frozen=True)
class ExtendedSpec:
    """A lamp (disc) or a sunlight patch (polygon) on the ceiling."""

    kind: str
    outline_xy: tuple[tuple[float, float], ...]
    z: float
    brightness: float
    radius_m: float = 0.0


@dataclass(frozen=True)
class PanelSpec:
    """Every landmark is a passive ceiling light: a rectangular panel (never switched, no
    radio), surveyed at its centre with `map_sigma_m` stated in the map."""

    width_m: float
    length_m: float
    angle_deg: float
    brightness: float
    map_sigma_m: float

    def outline_xy(self, x: float, y: float) -> FloatArray:
        """The panel's corners around its centre (x, y), metres, shape (4, 2)."""
        a = math.radians(self.angle_deg)
        u = np.array([math.cos(a), math.sin(a)]) * 0.5 * self.length_m
        v = np.array([-math.sin(a), math.cos(a)]) * 0.5 * self.width_m
        c = np.array([x, y])
        return np.array([c - u - v, c + u - v, c + u + v, c - u + v])


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
    bumps: tuple[FloorBump | FloorTilt, ...]
    robots: tuple[RobotSpec, ...]
    radio_latency_s: tuple[float, float]
    radio_loss: float
    render: RenderConfig
    slips: tuple[SlipPatch, ...] = ()
    floors: tuple[FloorSpec, ...] = (FloorSpec("0", "Floor 0", 0, 0.0),)
    panels: PanelSpec | None = None

    def with_lens(self, lens: Lens) -> Scenario:
        """The same scenario with every robot's camera on `lens`."""
        robots = tuple(
            dataclasses.replace(r, camera=dataclasses.replace(r.camera, lens=lens))
            for r in self.robots
        )
        return dataclasses.replace(self, robots=robots)

    def with_calibration(self, error: bool | CalibrationError) -> Scenario:
        """The same scenario with every robot's camera handed over with `error` (see
        `CameraSpec.calibration_error`)."""
        robots = tuple(
            dataclasses.replace(r, camera=dataclasses.replace(r.camera, calibration_error=error))
            for r in self.robots
        )
        return dataclasses.replace(self, robots=robots)


_TOP = (
    "panels",
    "name",
    "description",
    "seed",
    "duration_s",
    "survey_sigma_m",
    "ceiling_height_m",
    "ceiling_unevenness_m",
    "layout_seed",
    "lens",
    "landmarks",
    "landmark_grid",
    "landmark_pairs",
    "floors",
    "lamps",
    "sunlight",
    "glints",
    "people",
    "floor_bumps",
    "floor_tilt",
    "slip_patches",
    "radio",
    "render",
    "robots",
)


class _Layout:
    """Where generated landmarks go: the ceiling height, its unevenness (each landmark
    without its own z is that much higher or lower, uniform) and the jitter of irregular
    grids, drawn from `layout_seed` (a property of the building, not of a run's seed)."""

    def __init__(self, ceiling: float, unevenness: float, seed: int) -> None:
        self.ceiling, self.unevenness = ceiling, unevenness
        self.rng = np.random.default_rng(seed)

    def z(self, n: Node, key: str = "z") -> float:
        if n.has(key):
            return n.number(key, low=0.5)
        return self.ceiling + float(self.rng.uniform(-self.unevenness, self.unevenness))

    def jitter(self, amount: float) -> tuple[float, float]:
        dx, dy = self.rng.uniform(-amount, amount, 2)
        return float(dx), float(dy)


def _grid(g: Node, layout: _Layout) -> list[LandmarkSpec]:
    g.mapping(("first_id", "x0", "y0", "nx", "ny", "spacing_m", "z", "jitter_m"))
    first, nx, ny = g.integer("first_id"), g.integer("nx", low=1), g.integer("ny", low=1)
    x0, y0, s = g.number("x0"), g.number("y0"), g.number("spacing_m", low=0.05)
    jitter = g.number("jitter_m", 0.0, low=0.0, high=0.45 * s)
    out = []
    for j in range(ny):
        for i in range(nx):
            dx, dy = layout.jitter(jitter) if jitter else (0.0, 0.0)
            x, y = x0 + i * s + dx, y0 + j * s + dy
            out.append(LandmarkSpec(first + j * nx + i, x, y, layout.z(g)))
    return out


def _landmarks(doc: Node, layout: _Layout) -> tuple[LandmarkSpec, ...]:
    out: list[LandmarkSpec] = []
    for n in doc.child("landmarks").items():
        n.mapping(("id", "x", "y", "z", "charge", "dead", "led_dead", "radio", "capacity_mah"))
        out.append(
            LandmarkSpec(
                n.integer("id"),
                n.number("x"),
                n.number("y"),
                layout.z(n),
                n.number("charge", 1.0, low=0, high=1),
                n.boolean("dead", False),
                n.string("radio", "") or None,
                n.number("capacity_mah", 2500.0, low=0.001),
                n.boolean("led_dead", False),
            )
        )
    if doc.has("landmark_grid"):
        grids = doc.child("landmark_grid")
        for g in grids.items() if isinstance(grids.value, list) else [grids]:
            out += _grid(g, layout)
    for n in doc.child("landmark_pairs").items():
        n.mapping(("first_id", "x", "y", "spacing_m", "angle_deg", "z"))
        first, x, y = n.integer("first_id"), n.number("x"), n.number("y")
        half, a = 0.5 * n.number("spacing_m", low=0.05), math.radians(n.number("angle_deg", 0.0))
        dx, dy = half * math.cos(a), half * math.sin(a)
        out += [
            LandmarkSpec(first, x - dx, y - dy, layout.z(n)),
            LandmarkSpec(first + 1, x + dx, y + dy, layout.z(n)),
        ]
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


def _clutter(doc: Node, ceiling: float) -> tuple[tuple[ExtendedSpec, ...], tuple[GlintSpec, ...]]:
    ext: list[ExtendedSpec] = []
    for n in doc.child("lamps").items():
        n.mapping(("x", "y", "z", "radius_m", "brightness"))
        ext.append(
            ExtendedSpec(
                "lamp",
                ((n.number("x"), n.number("y")),),
                n.number("z", ceiling),
                n.number("brightness", 800.0, low=0),
                n.number("radius_m", 0.1, low=0.01),
            )
        )
    for n in doc.child("sunlight").items():
        n.mapping(("polygon", "z", "brightness"))
        ext.append(
            ExtendedSpec(
                "sunlight",
                _points(n, "polygon", 3),
                n.number("z", ceiling),
                n.number("brightness", 120.0, low=0),
            )
        )
    glints = []
    for n in doc.child("glints").items():
        n.mapping(("x", "y", "z", "intensity", "blink_period_s"))
        glints.append(
            GlintSpec(
                n.number("x"),
                n.number("y"),
                n.number("z", ceiling),
                n.number("intensity", 0.3, low=0),
                n.number("blink_period_s", 0.0, low=0),
            )
        )
    return tuple(ext), tuple(glints)


def _floors(doc: Node, layout: _Layout) -> tuple[tuple[FloorSpec, ...], tuple[LandmarkSpec, ...]]:
    """The building's floors and every landmark (each floor's own `landmarks`,
    `landmark_grid`, `landmark_pairs`; without `floors`: the document's, on floor "0")."""
    if not doc.has("floors"):
        return (FloorSpec("0", "Floor 0", 0, 0.0),), _landmarks(doc, layout)
    floors: list[FloorSpec] = []
    landmarks: list[LandmarkSpec] = []
    for n in doc.child("floors").items():
        n.mapping(
            ("id", "name", "level", "height_m", "landmarks", "landmark_grid", "landmark_pairs")
        )
        floor = FloorSpec(
            n.string("id"),
            n.string("name", f"Floor {n.string('id')}"),
            n.integer("level"),
            n.number("height_m", 0.0, low=-1000, high=1000),
        )
        if floor.id in {f.id for f in floors}:
            raise n.error(f"floor {floor.id!r} appears twice")
        floors.append(floor)
        landmarks += [dataclasses.replace(lm, floor=floor.id) for lm in _landmarks(n, layout)]
    seen: set[int] = set()
    for lm in landmarks:
        if lm.id in seen:
            raise doc.child("floors").error(
                f"landmark id {lm.id} appears twice (IDs are unique per site)"
            )
        seen.add(lm.id)
    return tuple(floors), tuple(landmarks)


def scenario_from_dict(data: object, *, source: str) -> Scenario:
    """Validate a parsed scenario document.

    Raises:
        ValueError: "SOURCE: field.path: what is wrong".
    """
    doc = Node(data, "", source).mapping(_TOP)
    ceiling = doc.number("ceiling_height_m", 2.5, low=0.5, high=20)
    layout = _Layout(
        ceiling,
        doc.number("ceiling_unevenness_m", 0.0, low=0.0, high=0.5 * ceiling),
        doc.integer("layout_seed", 0),
    )
    lens = doc.string("lens", "fisheye", choices=LENSES)
    robots = tuple(robot_from_node(n, lens) for n in doc.child("robots", required=True).items())  # type: ignore[arg-type]
    if not robots:
        raise doc.child("robots").error("expected at least one robot")
    if len({r.name for r in robots}) != len(robots):
        raise doc.child("robots").error("robot names must be unique")
    ext, glints = _clutter(doc, ceiling)
    floors, landmarks = _floors(doc, layout)
    for i, r in enumerate(robots):
        if r.floor not in {f.id for f in floors}:
            raise doc.child("robots").error(f"[{i}].floor: no floor {r.floor!r}")
    people = []
    for n in doc.child("people").items():
        n.mapping(("path", "speed_mps", "radius_m", "height_m"))
        people.append(
            PersonSpec(
                _points(n, "path", 2),
                n.number("speed_mps", 1.0, low=0),
                n.number("radius_m", 0.25, low=0.05),
                n.number("height_m", 1.8, low=0.1),
            )
        )
    bumps: list[FloorBump | FloorTilt] = []
    for n in doc.child("floor_bumps").items():
        n.mapping(("x", "y", "radius_m", "height_m"))
        bumps.append(
            FloorBump(
                n.number("x"),
                n.number("y"),
                n.number("radius_m", low=0.05),
                n.number("height_m", low=-0.2, high=0.2),
            )
        )
    bumps += _floor_tilt(doc)
    radio = doc.child("radio", {}).mapping(("latency_s", "loss"))
    latency = radio.child_vector("latency_s", 2, "[min, max] seconds", (0.01, 0.04))
    if not 0 <= latency[0] <= latency[1] <= 5:
        raise radio.child("latency_s").error(f"expected 0 <= min <= max <= 5 s, got {latency}")
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
        landmarks=landmarks,
        floors=floors,
        extended=ext,
        glints=glints,
        people=tuple(people),
        bumps=tuple(bumps),
        robots=robots,
        radio_latency_s=(latency[0], latency[1]),
        radio_loss=radio.number("loss", 0.02, low=0, high=0.9),
        render=render_cfg,
        slips=_slips(doc),
        panels=_panels(doc),
    )


def _panels(doc: Node) -> PanelSpec | None:
    """`panels:`: every landmark a passive light panel (docs/sim.md)."""
    if not doc.has("panels"):
        return None
    n = doc.child("panels").mapping(
        ("width_m", "length_m", "angle_deg", "brightness", "map_sigma_m")
    )
    return PanelSpec(
        n.number("width_m", 0.6, low=0.05, high=5),
        n.number("length_m", 0.6, low=0.05, high=5),
        n.number("angle_deg", 0.0),
        n.number("brightness", 300.0, low=1),
        n.number("map_sigma_m", 0.05, low=0.001, high=1),
    )


def _floor_tilt(doc: Node) -> list[FloorTilt]:
    if not doc.has("floor_tilt"):
        return []
    n = doc.child("floor_tilt").mapping(("slope_deg", "direction_deg", "x", "y"))
    return [
        FloorTilt(
            n.number("x", 0.0),
            n.number("y", 0.0),
            math.radians(n.number("slope_deg", low=-10, high=10)),
            math.radians(n.number("direction_deg", 0.0)),
        )
    ]


def _slips(doc: Node) -> tuple[SlipPatch, ...]:
    out = []
    for n in doc.child("slip_patches").items():
        n.mapping(("x", "y", "radius_m", "slip"))
        left, right = n.child_vector("slip", 2, "[left, right] slip (0..0.9)")
        if not (0 <= left <= 0.9 and 0 <= right <= 0.9):
            raise n.child("slip").error(f"each slip must be in [0, 0.9], got {[left, right]}")
        out.append(
            SlipPatch(n.number("x"), n.number("y"), n.number("radius_m", low=0.05), (left, right))
        )
    return tuple(out)


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
