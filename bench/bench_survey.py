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

Printed: error against drive time (p95 / max in x-y and z, the share of landmarks within
2 sigma, time to solve), and the one-at-a-time wizard on the same floor: one measurement
the median of five samples from localized frames, the LED's height assumed to be the
ceiling's (`commissioning/measuring.py`).

    .venv/bin/python bench/bench_survey.py [--minutes 15] [--seed 7]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from sim.survey_floor import SpotDrive, simulate_survey_spots, survey_floor_scenario
from survey.blinks import BlinkConfig, blink_schedule
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
        parse_survey_map(landmarks, source="bench map"), drive.camera,
        RobotGeometry(drive.wheel_base_m), drive.frame_t_ns[:nf], drive.frame_spots[:nf],
        drive.odom_t_ns[:no], drive.odom_v[:no], [c for c in drive.leds if c.t_ns <= end], 0,
    )  # fmt: skip


def score(result: SurveyResult, truth: dict[int, np.ndarray]) -> dict[str, float]:
    xy, z, inside = [], [], []
    for lid, e in result.landmarks.items():
        if e.anchor:
            continue
        d = e.position - truth[lid]
        xy.append(math.hypot(d[0], d[1]))
        z.append(abs(d[2]))
        # 2-sigma region of the horizontal error: Mahalanobis distance^2 <= 6.18 (2 dof, 95 %)
        c = e.covariance[:2, :2]
        inside.append(float(d[:2] @ np.linalg.solve(c, d[:2])) <= 6.18)
    a, b = np.array(xy), np.array(z)
    return {
        "n": len(a), "xy_p95": float(np.percentile(a, 95)), "xy_max": float(a.max()),
        "z_p95": float(np.percentile(b, 95)), "z_max": float(b.max()),
        "within_2sigma": float(np.mean(inside)),
    }  # fmt: skip


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
    a, b = np.array(xy), np.array(z)
    return {"n": len(a), "xy_p95": float(np.percentile(a, 95)), "xy_max": float(a.max()),
            "z_p95": float(np.percentile(b, 95)), "z_max": float(b.max())}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=15.0, help="longest drive, minutes")
    p.add_argument("--seed", type=int, default=7)
    args = p.parse_args(argv)
    scenario = survey_floor_scenario(seed=args.seed, n_landmarks=50)
    ids = sorted(lm.id for lm in scenario.landmarks)
    end_s = args.minutes * 60.0
    t0 = time.perf_counter()
    drive = simulate_survey_spots(
        scenario, end_s, lambda t: blink_schedule(ids, t, round(end_s * NS), BlinkConfig()),
        seed=args.seed,
    )  # fmt: skip
    print(f"simulated {end_s / 60:.0f} min of driving ({len(drive.frame_t_ns)} frames) "
          f"in {time.perf_counter() - t0:.0f} s")  # fmt: skip
    rng = np.random.default_rng(args.seed)
    anchors = farthest_pair(drive)
    landmarks = rough_map(drive, anchors, rng)
    print(
        "\n| drive min | surveyed | x-y p95 mm | x-y max mm | z p95 mm | z max mm "
        "| within 2 sigma | solve s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    minutes = [m for m in (2.0, 4.0, 8.0, 15.0) if m < args.minutes] + [args.minutes]
    for m in minutes:
        sd = truncated(drive, m * 60.0, landmarks)
        t1 = time.perf_counter()
        try:
            problem = survey_problem(sd, anchors)
            result = solve_survey(problem, BundleConfig())
        except ValueError as exc:
            print(f"| {m:.0f} | - | {exc} |")
            continue
        s = score(result, drive.landmarks_true)
        print(
            f"| {m:.0f} | {s['n']}/{len(ids) - 2} | {1000 * s['xy_p95']:.1f} "
            f"| {1000 * s['xy_max']:.1f} | {1000 * s['z_p95']:.1f} | {1000 * s['z_max']:.1f} "
            f"| {100 * s['within_2sigma']:.0f} % "
            f"| {time.perf_counter() - t1:.0f} |"
        )
    w = wizard(drive, anchors, rng)
    print(
        f"\nwizard, one landmark at a time ({w['n']} landmarks, five samples each, ceiling "
        f"height assumed): x-y p95 {1000 * w['xy_p95']:.1f} mm, max "
        f"{1000 * w['xy_max']:.1f} mm; z p95 {1000 * w['z_p95']:.1f} mm, max "
        f"{1000 * w['z_max']:.1f} mm; at ~20 s of robot and "
        f"staff time per landmark, {w['n'] * 20 / 60:.0f} min"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
