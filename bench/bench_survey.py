"""Survey benchmark: how well and how fast `irloc survey` places 50 landmarks by driving.

A 10 m x 8 m floor with 50 landmarks placed irregularly, ceiling 2.5 m +-5 cm
(`sim.survey_floor`); a robot drives lanes 2 m apart at 0.5 m/s for up to 15 minutes with the
usual odometry errors (wheel radii +0.4 % / -0.3 %, wheel base +1 %, 1 % speed noise) and a
camera whose calibration is off as Zhang's method leaves it (focal 0.2 %, principal point
0.6 px, distortion 5 %, 1 sigma). Two landmarks in opposite corners are anchors (surveyed to
1 mm); every other one is given off by up to 30 cm (uniform in a disc, height +-10 cm), and
ten of them with no position at all. The landmarks blink one at a time against the lit
ceiling (`survey.blinks`).

Spots are simulated at the level of their centres (true projection + 0.15 px noise) rather
than rendered: rendering 27,000 frames takes most of an hour on this machine; the rendered
path (detection and tracking on real images) is exercised by the test suite and by
`--rendered`, which surveys a rendered 150 s drive.

Printed per seed (a floor, a drive, a calibration error and an anchor survey of its own),
against drive time: landmarks located, error (p95 / max in x-y and z), the share within
2 sigma (x-y: inside the 2-sigma ellipse of the reported covariance, Mahalanobis^2 <= 6.18,
the 95.4 % region of 2 dof; z: within 2 sigma_z), the time to name the spots and to solve,
and the one-at-a-time wizard in the same robot time (~20 s a landmark: one measurement the
median of five samples from localized frames, the LED's height assumed to be the ceiling's,
`commissioning/measuring.py`). Then the 2-sigma coverage pooled over the seeds: the anchors'
1 mm survey error moves every landmark of one floor alike, so one floor's share is not 48
independent trials.

    .venv/bin/python bench/bench_survey.py [--minutes 2,5,10,15] [--seeds 7,8,9]

`--lit` surveys without blinks instead (`sim.lit_site`): 24 landmarks on 7.2 m x 4.8 m,
neighbours down to 70 cm, ceiling 2.5 m +-5 cm, every LED lit after the two anchors (in view
at the start, ~2.5 m apart) lit one at a time; every other landmark taped (x, y off by
sigma 12 cm, at most 30 cm; height the nominal ceiling's); a lawnmower drive at 0.5 m/s.
`--close-pairs N` adds N landmarks 30 cm from a neighbour (closer than the tape can tell
apart): they must be reported, never named wrongly. `--held-out` is a site never tuned on
(6 m x 6 m, 30 landmarks, the wide radial-tangential lens, 0.4 m/s, lanes 1 m apart).

    .venv/bin/python bench/bench_survey.py --lit --seeds 29,30,31,32 --minutes 3
    .venv/bin/python bench/bench_survey.py --lit --close-pairs 4 --seeds 29,30,31,32 --minutes 3
    .venv/bin/python bench/bench_survey.py --lit --held-out --seeds 101,102,103 --minutes 3
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np

from sim.survey_floor import SpotDrive, simulate_survey_spots, survey_floor_scenario
from survey.blinks import BlinkConfig, blink_schedule, blink_schedule_in_view
from survey.bundle import BundleConfig, solve_survey
from survey.ceiling import ceiling_points_world
from survey.drive import SurveyDrive, survey_problem
from survey.result import SurveyResult
from survey.survey_map import parse_survey_map

NS = 1_000_000_000


def farthest_pair(drive: SpotDrive) -> list[int]:
    """The two landmarks farthest apart (staff survey the two corners of the site)."""
    ids = sorted(drive.landmarks_true)
    p = np.array([drive.map_records[i]["x"] for i in range(len(ids))])
    q = np.array([drive.map_records[i]["y"] for i in range(len(ids))])
    d = np.hypot(p[:, None] - p[None, :], q[:, None] - q[None, :])
    i, j = np.unravel_index(int(np.argmax(d)), d.shape)
    return [int(drive.map_records[int(i)]["id"]), int(drive.map_records[int(j)]["id"])]  # type: ignore[call-overload]


def rough_map(drive: SpotDrive, anchors: list[int], rng: np.random.Generator) -> dict[str, object]:
    """map.json as staff would start from: anchors surveyed, the rest taped or unknown."""
    records = []
    no_position = set(
        rng.choice(
            [i for i in drive.landmarks_true if i not in anchors], 10, replace=False
        ).tolist()
    )
    for rec in drive.map_records:
        rec = dict(rec)
        lid = int(rec["id"])  # type: ignore[call-overload]
        if lid in no_position:
            for k in ("x", "y", "z"):
                rec.pop(k)
        elif lid not in anchors:
            a, r = rng.uniform(0, math.tau), 0.3 * math.sqrt(rng.uniform())
            rec["x"] = float(rec["x"]) + r * math.cos(a)  # type: ignore[arg-type]
            rec["y"] = float(rec["y"]) + r * math.sin(a)  # type: ignore[arg-type]
            rec["z"] = float(rec["z"]) + rng.uniform(-0.1, 0.1)  # type: ignore[arg-type]
        records.append(rec)
    return {"landmarks": records}


def truncated(drive: SpotDrive, seconds: float, landmarks: dict[str, object]) -> SurveyDrive:
    """The first `seconds` of the drive as the survey reads a recording."""
    end = seconds * NS
    nf = int(np.searchsorted(drive.frame_t_ns, end))
    no = int(np.searchsorted(drive.odom_t_ns, end))
    from localizer.robot import RobotGeometry

    return SurveyDrive(
        parse_survey_map(landmarks, source="bench map"),
        drive.camera,
        RobotGeometry(drive.wheel_base_m),
        drive.frame_t_ns[:nf],
        drive.frame_spots[:nf],
        drive.odom_t_ns[:no],
        drive.odom_v[:no],
        [c for c in drive.leds if c.t_ns <= end],
        0,
    )


def error_figures(xy: list[float], z: list[float]) -> dict[str, float]:
    """Count, p95 and max of the horizontal and vertical errors, metres."""
    a, b = np.array(xy), np.array(z)
    return {
        "n": len(a),
        "xy_p95": float(np.percentile(a, 95)),
        "xy_max": float(a.max()),
        "z_p95": float(np.percentile(b, 95)),
        "z_max": float(b.max()),
    }


def score(result: SurveyResult, truth: dict[int, np.ndarray]) -> dict[str, float]:
    """Errors against the truth and the sigmas' honesty: the share within 2 sigma and the
    normalised squared error (x-y Mahalanobis^2, 2 on average when the covariance is
    honest; above: over-confident, below: over-cautious)."""
    xy, z, inside, inside_z, nees = [], [], [], [], []
    for lid, e in result.landmarks.items():
        if e.anchor:
            continue
        d = e.position - truth[lid]
        xy.append(math.hypot(d[0], d[1]))
        z.append(abs(d[2]))
        # 2-sigma region of the horizontal error: Mahalanobis distance^2 <= 6.18 (2 dof,
        # the 95.4 % of 2 sigma in one dimension)
        c = e.covariance[:2, :2]
        nees.append(float(d[:2] @ np.linalg.solve(c, d[:2])))
        inside.append(nees[-1] <= 6.18)
        inside_z.append(abs(d[2]) <= 2.0 * e.sigma_z_m)
    return error_figures(xy, z) | {
        "inside_xy": float(np.sum(inside)),
        "inside_z": float(np.sum(inside_z)),
        "nees_xy": float(np.sum(nees)),
    }


def wizard(drive: SpotDrive, anchors: list[int], rng: np.random.Generator) -> dict[str, float]:
    """One landmark at a time, as `commissioning/measuring.py` measures: the median of five
    samples, each a spot placed on the ceiling from the robot's pose as the localizer gives it
    (1 sigma 5 mm, 0.05 deg), the LED's height assumed to be the ceiling's (the anchors')."""
    from localizer.camera import predict_pixels
    from localizer.geometry import T_world_body_from_pose

    z_ceiling = float(np.mean([drive.landmarks_true[a][2] for a in anchors]))
    xy, z = [], []
    for lid, p in drive.landmarks_true.items():
        if lid in anchors:
            continue
        samples = []
        for f in range(0, len(drive.frame_t_ns), 15):
            pose = drive.truth[f]
            px, ok = predict_pixels(drive.camera_true, T_world_body_from_pose(*pose), p[None, :])
            if ok[0] and np.linalg.norm(px[0] - [drive.camera.cu, drive.camera.cv]) < 150:
                seen = pose + rng.normal(0.0, [0.005, 0.005, math.radians(0.05)])
                q, hit = ceiling_points_world(
                    drive.camera, seen[None, :], px[:1] + rng.normal(0, 0.15, 2), z_ceiling
                )
                if hit[0]:
                    samples.append(q[0])
            if len(samples) == 5:
                break
        if samples:
            d = np.median(np.array(samples), axis=0) - p
            xy.append(math.hypot(d[0], d[1]))
            z.append(abs(d[2]))
    return error_figures(xy, z)


def wizard_in(minutes: float, w: dict[str, float], per_landmark_s: float = 20.0) -> str:
    """What the wizard gets in the same robot (and staff) time: landmarks measured, errors."""
    n = min(int(minutes * 60.0 // per_landmark_s), int(w["n"]))
    return f"{n} | {1000 * w['xy_p95']:.0f} | {1000 * w['z_p95']:.0f}" if n else "0 | - | -"


def in_view_along(
    drive: SpotDrive,
    landmarks: dict[str, object],
    rng: np.random.Generator,
    margin_px: float = 60.0,
) -> Callable[[int], list[int]]:
    """What the site expects the robot to see well inside its image at a time: the map's
    positions (rough ones too) projected from the robot's pose as its localizer has it
    (the drive's pose, 2 cm and 0.5 deg off), nearest the image's centre first."""
    from localizer.camera import predict_pixels
    from localizer.geometry import T_world_body_from_pose

    recs = [r for r in landmarks["landmarks"] if "x" in r]  # type: ignore[attr-defined]
    ids = np.array([int(r["id"]) for r in recs])
    pos = np.array([[float(r[k]) for k in "xyz"] for r in recs])
    cam = drive.camera
    centre = np.array([cam.cu, cam.cv])

    def in_view(t_ns: int) -> list[int]:
        f = min(int(np.searchsorted(drive.frame_t_ns, t_ns)), len(drive.frame_t_ns) - 1)
        pose = drive.truth[f] + rng.normal(0.0, [0.02, 0.02, math.radians(0.5)])
        px, ok = predict_pixels(cam, T_world_body_from_pose(*pose), pos)
        inside = (
            ok
            & (px[:, 0] >= margin_px)
            & (px[:, 0] <= cam.width - 1 - margin_px)
            & (px[:, 1] >= margin_px)
            & (px[:, 1] <= cam.height - 1 - margin_px)
        )
        order = np.argsort(np.linalg.norm(px - centre, axis=1))
        return [int(ids[i]) for i in order if inside[i]]

    return in_view


def survey_seed(
    seed: int, minutes: list[float], aimed: bool, exact_anchors: bool = False
) -> list[dict[str, float]]:
    """One floor: simulate the longest drive, survey its first `minutes`, print a table.

    With `aimed`, the blinks go to the landmarks the robot sees (`blink_schedule_in_view`,
    as the live survey does): the drive is simulated once with every landmark lit for its
    route, then again with the blinks (the robot's motion does not depend on the LEDs).
    With `exact_anchors`, the anchors are surveyed without error and the survey told so
    (the share within 2 sigma then tests everything but the anchors' survey, landmark by
    landmark; with 1 mm anchors every landmark of a floor shares its anchors' error).
    """
    scenario = survey_floor_scenario(
        seed=seed, n_landmarks=50, survey_sigma_m=0.0 if exact_anchors else 0.001
    )
    config = BundleConfig(anchor_sigma_m=1e-5) if exact_anchors else BundleConfig()
    ids = sorted(lm.id for lm in scenario.landmarks)
    end_s = max(minutes) * 60.0
    end_ns = round(end_s * NS)
    t0 = time.perf_counter()
    drive = simulate_survey_spots(
        scenario, end_s, lambda t: blink_schedule(ids, t, end_ns, BlinkConfig()), seed=seed
    )
    rng = np.random.default_rng(seed)
    anchors = farthest_pair(drive)
    landmarks = rough_map(drive, anchors, rng)
    if aimed:
        see = in_view_along(drive, landmarks, np.random.default_rng(seed + 1000))
        route = drive.truth
        drive = simulate_survey_spots(
            scenario,
            end_s,
            lambda t: blink_schedule_in_view(ids, t, end_ns, BlinkConfig(), see),
            seed=seed,
        )
        if not np.array_equal(route, drive.truth):
            print("warning: the drive with blinks took another path than the one planned")
    print(
        f"\nseed {seed}: simulated {end_s / 60:.0f} min of driving "
        f"({len(drive.frame_t_ns)} frames) in {time.perf_counter() - t0:.0f} s, blinks "
        f"{'aimed at the landmarks in view' if aimed else 'round robin'}"
    )
    w = wizard(drive, anchors, rng)
    print(
        "\n| drive min | located | x-y p95 mm | x-y max mm | z p95 mm | z max mm "
        "| x-y in 2 sigma | z in 2 sigma | naming s | solve s "
        "| wizard located | wizard x-y p95 mm | wizard z p95 mm |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for m in minutes:
        sd = truncated(drive, m * 60.0, landmarks)
        t1 = time.perf_counter()
        try:
            problem = survey_problem(sd, anchors)
            t2 = time.perf_counter()
            result = solve_survey(problem, config)
        except ValueError as exc:
            print(f"| {m:.0f} | - | {exc} |")
            continue
        t3 = time.perf_counter()
        s = score(result, drive.landmarks_true)
        n = s["n"]
        print(
            f"| {m:.0f} | {n:.0f}/{len(ids) - 2} | {1000 * s['xy_p95']:.1f} "
            f"| {1000 * s['xy_max']:.1f} | {1000 * s['z_p95']:.1f} | {1000 * s['z_max']:.1f} "
            f"| {100 * s['inside_xy'] / n:.0f} % | {100 * s['inside_z'] / n:.0f} % "
            f"| {t2 - t1:.0f} | {t3 - t2:.0f} | {wizard_in(m, w)} |",
            flush=True,
        )
        rows.append({"minutes": m, **s})
    print(
        f"wizard, one landmark at a time ({w['n']} landmarks, five samples each, ceiling "
        f"height assumed): x-y p95 {1000 * w['xy_p95']:.1f} mm, max "
        f"{1000 * w['xy_max']:.1f} mm; z p95 {1000 * w['z_p95']:.1f} mm, max "
        f"{1000 * w['z_max']:.1f} mm; ~20 s of robot and staff time a landmark, "
        f"{w['n'] * 20 / 60:.0f} min for all"
    )
    return rows


def lit_seed(
    seed: int, minutes: list[float], close_pairs: int, held_out: bool
) -> list[dict[str, float]]:
    """One site surveyed with every LED lit after the anchors' sweep (`--lit`)."""
    from sim.lit_site import anchor_pair, anchor_sweep_then_lit, lit_site_scenario, taped_map

    shape: dict[str, object] = (
        {
            "size_m": (6.0, 6.0),
            "n_landmarks": 30,
            "min_spacing_m": 0.75,
            "lens": "wide_radtan",
            "speed_mps": 0.4,
            "lane_spacing_m": 1.0,
        }
        if held_out
        else {}
    )
    scenario = lit_site_scenario(seed=seed, close_pairs=close_pairs, **shape)  # type: ignore[arg-type]
    anchors = anchor_pair(scenario)
    end_s = max(minutes) * 60.0
    drive = simulate_survey_spots(
        scenario, end_s, lambda t: anchor_sweep_then_lit(anchors), seed=seed
    )
    landmarks = taped_map(drive.map_records, anchors, np.random.default_rng(seed))
    truth = drive.landmarks_true
    pts = np.array([truth[i][:2] for i in sorted(truth)])
    gaps = np.linalg.norm(pts[:, None] - pts[None], axis=2) + 1e9 * np.eye(len(pts))
    print(
        f"\nseed {seed}: {len(truth)} landmarks (nearest neighbours {100 * gaps.min():.0f}"
        f"-{100 * gaps.min(axis=1).max():.0f} cm), anchors {anchors}, every LED lit after "
        f"their sweep\n\n| drive min | located | unnamed (reason) | wrong | x-y p95 mm "
        "| x-y max mm | z p95 mm | z max mm | x-y in 2 sigma | z in 2 sigma | solve s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for m in minutes:
        sd = truncated(drive, m * 60.0, landmarks)
        t1 = time.perf_counter()
        result = solve_survey(survey_problem(sd, anchors), BundleConfig())
        t2 = time.perf_counter()
        wrong = [
            lid
            for lid, e in result.landmarks.items()
            if math.hypot(*(e.position - truth[lid])[:2]) > 0.1
        ]
        reasons: dict[str, int] = {}
        for why in result.unnamed.values():
            key = why.split(" (")[0].split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
        s = score(result, truth)
        n = s["n"]
        print(
            f"| {m:.0f} | {n:.0f}/{len(truth) - 2} "
            f"| {len(result.unnamed)} ({'; '.join(f'{v} {k}' for k, v in reasons.items())}) "
            f"| {len(wrong)} | {1000 * s['xy_p95']:.1f} | {1000 * s['xy_max']:.1f} "
            f"| {1000 * s['z_p95']:.1f} | {1000 * s['z_max']:.1f} "
            f"| {100 * s['inside_xy'] / n:.0f} % | {100 * s['inside_z'] / n:.0f} % "
            f"| {t2 - t1:.0f} |",
            flush=True,
        )
        rows.append({"minutes": m, "wrong": float(len(wrong)), **s})
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", default="2,5,10,15", help="drive times, minutes")
    p.add_argument("--seeds", default="7", help="floors, comma-separated seeds")
    p.add_argument(
        "--round-robin",
        action="store_true",
        help="blink every landmark in turn instead of those the robot sees",
    )
    p.add_argument(
        "--exact-anchors",
        action="store_true",
        help="anchors surveyed without error (tests the sigmas landmark by landmark)",
    )
    p.add_argument("--lit", action="store_true", help="no blinks: every LED lit (see above)")
    p.add_argument("--close-pairs", type=int, default=0, help="--lit: landmarks 30 cm apart")
    p.add_argument("--held-out", action="store_true", help="--lit: the site never tuned on")
    args = p.parse_args(argv)
    minutes = sorted(float(m) for m in args.minutes.split(","))
    seeds = [int(x) for x in args.seeds.split(",")]
    if args.lit:
        rows = [
            r for seed in seeds for r in lit_seed(seed, minutes, args.close_pairs, args.held_out)
        ]
    else:
        rows = [
            r
            for seed in seeds
            for r in survey_seed(seed, minutes, not args.round_robin, args.exact_anchors)
        ]
    print(f"\npooled over {len(seeds)} seed(s): landmarks within 2 sigma (expected ~95 %)")
    for m in minutes:
        sel = [r for r in rows if r["minutes"] == m]
        n = sum(r["n"] for r in sel)
        if n:
            xy = sum(r["inside_xy"] for r in sel)
            z = sum(r["inside_z"] for r in sel)
            nees = sum(r["nees_xy"] for r in sel) / n
            print(
                f"  {m:.0f} min: x-y {xy:.0f}/{n:.0f} ({100 * xy / n:.0f} %), "
                f"z {z:.0f}/{n:.0f} ({100 * z / n:.0f} %); x-y error^2 / covariance "
                f"{nees:.2f} on average (2: honest); sites with every landmark within: "
                f"{sum(r['inside_xy'] == r['n'] for r in sel)}/{len(sel)}"
            )
            if args.lit:
                e = np.array([r["xy_p95"] for r in sel]) * 1000
                print(
                    f"  {m:.0f} min: named wrongly {sum(r['wrong'] for r in sel):.0f}; "
                    f"x-y p95 per site {', '.join(f'{v:.1f}' for v in e)} mm, max "
                    f"{1000 * max(r['xy_max'] for r in sel):.1f} mm, z max "
                    f"{1000 * max(r['z_max'] for r in sel):.1f} mm"
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
