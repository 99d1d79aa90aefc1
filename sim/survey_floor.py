"""A floor to survey: irregularly placed landmarks on an uneven ceiling and a robot driving
lanes under them (the test bed of `irloc survey`, `bench/bench_survey.py`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from localizer.camera import CameraModel, predict_pixels
from localizer.events import LedsChanged, OdometryMeasured
from localizer.types import FloatArray, IntArray
from sim.build import build_robot, build_world, seed_generators
from sim.cameras import perturbed_camera
from sim.robot import FloorArrival
from sim.scenario import Scenario, scenario_from_dict


def survey_floor_scenario(
    *,
    seed: int = 7,
    n_landmarks: int = 50,
    size_m: tuple[float, float] = (10.0, 8.0),
    ceiling_m: float = 2.5,
    ceiling_spread_m: float = 0.05,
    lane_spacing_m: float = 2.0,
    speed_mps: float = 0.5,
    lens: str = "fisheye",
    survey_sigma_m: float = 0.001,
) -> Scenario:
    """Landmarks jittered off a grid (about one per square metre / n), heights within
    +-`ceiling_spread_m`, and a robot driving lanes `lane_spacing_m` apart, back and forth.

    The robot has the usual odometry errors (wheel radii, wheel base) and its camera the
    usual calibration error; `survey_sigma_m` is the error of map.json (the anchors' survey).
    """
    rng = np.random.default_rng(seed)
    w, h = size_m
    nx = max(2, round(math.sqrt(n_landmarks * w / h)))
    ny = math.ceil(n_landmarks / nx)
    sx, sy = w / nx, h / ny
    cells = [(i, j) for j in range(ny) for i in range(nx)][:n_landmarks]
    landmarks = []
    for k, (i, j) in enumerate(cells):
        x = (i + 0.5) * sx + rng.uniform(-0.35, 0.35) * sx
        y = (j + 0.5) * sy + rng.uniform(-0.35, 0.35) * sy
        z = ceiling_m + rng.uniform(-ceiling_spread_m, ceiling_spread_m)
        landmarks.append({"id": 100 + k, "x": round(x, 4), "y": round(y, 4), "z": round(z, 4)})
    lanes = max(2, math.floor(h / lane_spacing_m) + 1)
    ys = np.linspace(0.6, h - 0.6, lanes)
    waypoints: list[list[float]] = []
    for n, y in enumerate(ys):
        xs = (0.6, w - 0.6) if n % 2 == 0 else (w - 0.6, 0.6)
        waypoints += [[xs[0], float(y)], [xs[1], float(y)]]
    waypoints += [list(p) for p in reversed(waypoints[1:-1])]
    return surveyor_scenario(
        name="survey_floor",
        description=f"{n_landmarks} landmarks, irregular, ceiling +-{ceiling_spread_m} m",
        seed=seed,
        landmarks=landmarks,
        start=[0.6, float(ys[0]), 0.0],
        waypoints=waypoints,
        speed_mps=speed_mps,
        ceiling_m=ceiling_m,
        lens=lens,
        survey_sigma_m=survey_sigma_m,
    )


def surveyor_scenario(
    *,
    name: str,
    description: str,
    seed: int,
    landmarks: list[dict[str, float]],
    start: list[float],
    waypoints: list[list[float]],
    speed_mps: float,
    ceiling_m: float,
    lens: str,
    survey_sigma_m: float,
) -> Scenario:
    """A survey test bed: `landmarks` (id, x, y, z) and one robot, "surveyor", looping over
    `waypoints` from `start` (x, y, theta) at `speed_mps`, with the usual odometry errors
    (wheel radii +0.4 / -0.3 %, wheel base +1 %, 1 % speed noise at 100 Hz), 1 % of its
    frames dropped, and a radio of 10-30 ms latency that loses nothing. `survey_sigma_m` is
    the error of map.json (the anchors' survey)."""
    return scenario_from_dict(
        {
            "name": name,
            "description": description,
            "seed": seed,
            "survey_sigma_m": survey_sigma_m,
            "ceiling_height_m": ceiling_m,
            "lens": lens,
            "landmarks": landmarks,
            "radio": {"latency_s": [0.01, 0.03], "loss": 0.0},
            "robots": [
                {
                    "name": "surveyor",
                    "start": start,
                    "wheel_base_m": 0.36,
                    "max_speed_mps": 1.0,
                    "wheel_radius_error": [0.004, -0.003],
                    "wheel_base_error": 0.01,
                    "odometry": {"rate_hz": 100, "noise_rel": 0.01},
                    "camera": {"drop_rate": 0.01},
                    "route": {"loop": True, "speed_mps": speed_mps, "waypoints": waypoints},
                }
            ],
        },
        source=name,
    )


@dataclass(frozen=True, eq=False)
class SpotDrive:
    """A survey drive simulated at the level of spot centres (no images rendered).

    Attributes:
        camera: the nominal camera (what calibration says); camera_true: what renders.
        wheel_base_m: nominal wheel base.
        frame_t_ns, frame_spots: each frame's time and its spot centres (N_f, 2), pixels.
        odom_t_ns, odom_v: wheel speeds as measured.
        leds: LED states in force from their times.
        truth_t_ns, truth: the true planar pose at each frame.
        landmarks_true: id -> true position (3,); map_records: map.json as surveyed.
    """

    camera: CameraModel
    camera_true: CameraModel
    wheel_base_m: float
    frame_t_ns: IntArray
    frame_spots: list[FloatArray]
    odom_t_ns: IntArray
    odom_v: FloatArray
    leds: list[LedsChanged]
    truth_t_ns: IntArray
    truth: FloatArray
    landmarks_true: dict[int, FloatArray]
    map_records: list[dict[str, object]]


def simulate_survey_spots(
    scenario: Scenario,
    duration_s: float,
    led_program: Callable[[int], Sequence[LedsChanged]],
    *,
    seed: int = 0,
    centroid_sigma_px: float = 0.15,
    focal_rel_sigma: float = 0.002,
    principal_sigma_px: float = 0.6,
    distortion_rel_sigma: float = 0.05,
) -> SpotDrive:
    """Drive the scenario's first robot and report the spots its camera would see.

    The same robot, odometry and world as `simulate_recording`, but each lit landmark in
    view becomes its true projection plus Gaussian centroid noise instead of a rendered spot
    (rendering a 15-minute drive takes most of an hour here). The true camera differs from
    the nominal one by a calibration error as Zhang's method leaves it: focal
    `focal_rel_sigma`, principal point `principal_sigma_px`, each distortion coefficient
    `distortion_rel_sigma` of itself (1 sigma), plus the mounting error of
    `sim.cameras.perturbed_camera`.
    """
    gens = seed_generators(seed, 4)
    world = build_world(scenario, gens[0])
    rig = build_robot(scenario.robots[0], scenario, gens[3], index=0)
    nominal = rig.camera_nominal
    true = perturbed_camera(
        nominal,
        gens[1],
        focal_rel_sigma=focal_rel_sigma,
        principal_sigma_px=principal_sigma_px,
        distortion_sigma=0.0,
    )
    d = np.asarray(true.distortion).copy()
    d *= 1.0 + gens[1].normal(0.0, distortion_rel_sigma, len(d))
    true = dataclasses.replace(true, distortion=d)
    ids = np.array(sorted(world.landmarks))
    p_true = np.array([world.landmarks[i].p_true for i in ids])
    end_ns = round(duration_s * 1e9)
    program = list(led_program(0))
    leds = program if program and program[0].t_ns <= 0 else [LedsChanged(0, all_lit=True), *program]
    times = [c.t_ns for c in leds]
    frame_t: list[int] = []
    spots: list[FloatArray] = []
    odom_t: list[int] = []
    odom_v: list[tuple[float, float]] = []
    truth: list[tuple[float, float, float]] = []
    rng = gens[2]
    t_ns = 0
    while t_ns < end_ns:
        t_ns = min(t_ns + 100_000_000, end_ns)
        for item in rig.robot.advance_to(t_ns):
            if isinstance(item, OdometryMeasured):
                odom_t.append(item.t_ns)
                odom_v.append((item.v_left, item.v_right))
                continue
            if isinstance(item, FloorArrival):  # a survey drive stays on its floor
                continue
            state = leds[int(np.searchsorted(times, item.t_ns, side="right")) - 1]
            lit = np.ones(len(ids), dtype=bool) if state.all_lit else np.isin(ids, list(state.lit))
            px, valid = predict_pixels(true, item.T_world_body, p_true)
            keep = valid & lit
            frame_t.append(item.t_ns)
            spots.append(px[keep] + rng.normal(0.0, centroid_sigma_px, (int(keep.sum()), 2)))
            truth.append(item.pose)
    return SpotDrive(
        camera=nominal,
        camera_true=true,
        wheel_base_m=rig.geometry.wheel_base,
        frame_t_ns=np.array(frame_t, dtype=np.int64),
        frame_spots=spots,
        odom_t_ns=np.array(odom_t, dtype=np.int64),
        odom_v=np.array(odom_v).reshape(-1, 2),
        leds=leds,
        truth_t_ns=np.array(frame_t, dtype=np.int64),
        truth=np.array(truth).reshape(-1, 3),
        landmarks_true={int(i): p for i, p in zip(ids.tolist(), p_true, strict=True)},
        map_records=world.landmark_records(),
    )
