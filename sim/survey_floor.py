"""A floor to survey: irregularly placed landmarks on an uneven ceiling and a robot driving
lanes under them (the test bed of `irloc survey`, `bench/bench_survey.py`).
"""

from __future__ import annotations

import math

import numpy as np

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
    return scenario_from_dict(
        {
            "name": "survey_floor",
            "description": f"{n_landmarks} landmarks, irregular, ceiling +-{ceiling_spread_m} m",
            "seed": seed,
            "survey_sigma_m": survey_sigma_m,
            "ceiling_height_m": ceiling_m,
            "lens": lens,
            "landmarks": landmarks,
            "radio": {"latency_s": [0.01, 0.03], "loss": 0.0},
            "robots": [
                {
                    "name": "surveyor",
                    "start": [0.6, float(ys[0]), 0.0],
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
        source="survey_floor",
    )
