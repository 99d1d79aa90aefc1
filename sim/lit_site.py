"""A site surveyed from an everyday drive: every LED lit after a short start in which the
two anchors light one at a time (the paper's sweep), a taped map, a lawnmower drive.

The test bed of surveying without blinks (`bench/bench_survey.py --lit`,
`tests/survey/test_association.py`): landmarks placed irregularly with neighbours down to
`min_spacing_m` apart (and optionally a few pairs closer than the tape can tell apart),
ceiling height +-`ceiling_spread_m`, the robot's usual odometry and calibration errors.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.events import LedsChanged
from sim.scenario import Scenario
from sim.survey_floor import surveyor_scenario


def _place(
    rng: np.random.Generator,
    size_m: tuple[float, float],
    n: int,
    min_spacing_m: float,
    margin_m: float,
) -> list[tuple[float, float]]:
    """`n` points jittered off a grid over the floor, no two closer than `min_spacing_m`
    (each redrawn until it fits), so neighbours range from that spacing to twice the grid's."""
    w, h = size_m
    nx = max(2, round(math.sqrt(n * w / h)))
    ny = math.ceil(n / nx)
    sx, sy = (w - 2 * margin_m) / nx, (h - 2 * margin_m) / ny
    out: list[tuple[float, float]] = []
    for i, j in [(i, j) for j in range(ny) for i in range(nx)][:n]:
        for _ in range(1000):
            x = margin_m + (i + 0.5 + rng.uniform(-0.45, 0.45)) * sx
            y = margin_m + (j + 0.5 + rng.uniform(-0.45, 0.45)) * sy
            if all(math.hypot(x - a, y - b) >= min_spacing_m for a, b in out):
                break
        else:
            raise ValueError(f"cannot place {n} landmarks {min_spacing_m} m apart on {size_m}")
        out.append((x, y))
    return out


def lit_site_scenario(
    *,
    seed: int = 29,
    size_m: tuple[float, float] = (7.2, 4.8),
    n_landmarks: int = 24,
    min_spacing_m: float = 0.7,
    close_pairs: int = 0,
    close_spacing_m: float = 0.3,
    ceiling_m: float = 2.5,
    ceiling_spread_m: float = 0.05,
    lane_spacing_m: float = 1.2,
    speed_mps: float = 0.5,
    lens: str = "fisheye",
    first_id: int = 401,
) -> Scenario:
    """Landmarks placed irregularly (`_place`); with `close_pairs`, that many of them get a
    neighbour `close_spacing_m` away (extra landmarks, closer than a taped map can tell
    apart). The robot mows the floor: lanes along x `lane_spacing_m` apart, then along y,
    then back, in a loop; it starts in a corner with the first two landmarks (the anchors,
    `anchor_pair`) in view.
    """
    rng = np.random.default_rng(seed)
    w, h = size_m
    xy = _place(rng, size_m, n_landmarks, min_spacing_m, 0.3)
    for k in range(close_pairs):
        x, y = xy[2 + (k * 5) % (n_landmarks - 2)]
        a = rng.uniform(0, math.tau)
        xy.append((x + close_spacing_m * math.cos(a), y + close_spacing_m * math.sin(a)))
    landmarks = [
        {
            "id": first_id + k,
            "x": round(x, 4),
            "y": round(y, 4),
            "z": round(ceiling_m + rng.uniform(-ceiling_spread_m, ceiling_spread_m), 4),
        }
        for k, (x, y) in enumerate(xy)
    ]
    m = 0.6
    ys = np.arange(m, h - m + 1e-9, lane_spacing_m)
    xs = np.arange(m, w - m + 1e-9, lane_spacing_m)
    mow: list[list[float]] = []
    for n, y in enumerate(ys):
        a, b = (m, w - m) if n % 2 == 0 else (w - m, m)
        mow += [[a, float(y)], [b, float(y)]]
    end = mow[-1]
    for n, x in enumerate(xs if end[0] < w / 2 else xs[::-1]):
        a, b = (end[1], h - end[1]) if n % 2 == 0 else (h - end[1], end[1])
        mow += [[float(x), a], [float(x), b]]
    start = [m, m, 0.0]
    return surveyor_scenario(
        name="lit_site",
        description=f"{len(landmarks)} landmarks, every LED lit, lawnmower drive",
        seed=seed,
        landmarks=landmarks,
        start=start,
        waypoints=mow,
        speed_mps=speed_mps,
        ceiling_m=ceiling_m,
        lens=lens,
        survey_sigma_m=0.001,
    )


def anchor_pair(scenario: Scenario, reach_m: tuple[float, float] = (1.5, 2.5)) -> list[int]:
    """The two anchors: of the landmarks within `reach_m` (x, y) of the robot's start (well
    inside its camera's view there), the two farthest apart."""
    x0, y0 = scenario.robots[0].start[:2]
    near = [
        lm
        for lm in scenario.landmarks
        if abs(lm.x - x0) <= reach_m[0] and abs(lm.y - y0) <= reach_m[1]
    ]
    if len(near) < 2:
        raise ValueError(f"fewer than two landmarks within {reach_m} m of the start")
    best = max(
        ((a, b) for i, a in enumerate(near) for b in near[i + 1 :]),
        key=lambda p: math.hypot(p[0].x - p[1].x, p[0].y - p[1].y),
    )
    return sorted([best[0].id, best[1].id])


def anchor_sweep_then_lit(anchors: list[int], dwell_s: float = 0.5) -> list[LedsChanged]:
    """The LED program: each anchor alone lit for `dwell_s` in turn, then every LED lit."""
    ns = round(dwell_s * 1e9)
    out = [LedsChanged(k * ns, lit=frozenset({a})) for k, a in enumerate(anchors)]
    return [*out, LedsChanged(len(anchors) * ns, all_lit=True)]


def taped_map(
    records: list[dict[str, object]],
    anchors: list[int],
    rng: np.random.Generator,
    *,
    sigma_m: float = 0.12,
    max_m: float = 0.30,
    ceiling_m: float = 2.5,
) -> dict[str, object]:
    """map.json as staff tape it: the anchors as surveyed, every other landmark's x and y off
    by a Gaussian error of `sigma_m` per axis (redrawn beyond `max_m`), its height the
    nominal ceiling's."""
    out = []
    for rec in records:
        rec = dict(rec)
        if int(rec["id"]) not in anchors:  # type: ignore[call-overload]
            while True:
                e = rng.normal(0.0, sigma_m, 2)
                if math.hypot(*e) <= max_m:
                    break
            rec["x"] = float(rec["x"]) + float(e[0])  # type: ignore[arg-type]
            rec["y"] = float(rec["y"]) + float(e[1])  # type: ignore[arg-type]
            rec["z"] = ceiling_m
        out.append(rec)
    return {"landmarks": out}
