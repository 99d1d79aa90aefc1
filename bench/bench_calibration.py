"""Calibration timing and accuracy.

- lens: `calibrate_lens` on OpenCV's 13 sample photos (pinhole and fisheye), wall time;
- synthetic fisheye: 13 rendered board photos of the virtual site's fisheye camera, the
  focal-length and principal-point errors;
- mounting: Monte Carlo over seeds of the simulated turn-in-place + straight manoeuvre
  (0.3 px pixel noise), yaw and offset errors (max and RMS) and the time per estimate.

    .venv/bin/python bench/bench_calibration.py [--seeds 20]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from calibration.board import BoardSpec  # noqa: E402
from calibration.lens import calibrate_lens  # noqa: E402
from calibration.mounting import mounting_from_observations  # noqa: E402
from localizer.camera import T_body_camera_upward  # noqa: E402
from sim.cameras import wide_angle_camera  # noqa: E402
from sim.chessboard import BoardRenderer, board_pose_facing  # noqa: E402
from tests.calibration.test_lens_synthetic import PIXELS  # noqa: E402
from tests.calibration.test_mounting import (  # noqa: E402
    WHEEL_BASE,
    _drive,
    _landmarks,
    _observations,
)


def bench_lens() -> None:
    paths = sorted((ROOT / "tests" / "data" / "chessboard").glob("left*.jpg"))
    images = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in paths]
    for model in ("pinhole", "fisheye"):
        t0 = time.perf_counter()
        result = calibrate_lens(images, model=model)  # type: ignore[arg-type]
        dt = time.perf_counter() - t0
        print(
            f"lens {model:8s} {len(images)} photos: {dt:.2f} s, RMS {result.rms_px:.3f} px, "
            f"fu {result.camera.fu:.2f}"
        )


def bench_synthetic_fisheye() -> None:
    camera = dataclasses.replace(wide_angle_camera("fisheye"), cu=326.3, cv=236.8)
    board = BoardSpec((9, 6), 0.02)
    t0 = time.perf_counter()
    renderer = BoardRenderer(camera, board, supersample=3)
    rng = np.random.default_rng(3)
    photos = [
        renderer.render(
            board_pose_facing(
                camera,
                board,
                p,
                0.33 + 0.04 * (k % 3),
                tilt_xy_rad=(0.45 * np.sin(2 * k), 0.45 * np.cos(1.3 * k)),
                roll_rad=0.25 * k,
            ),
            rng=rng,
        )
        for k, p in enumerate(PIXELS)
    ]
    t_render = time.perf_counter() - t0
    result = calibrate_lens(photos, model="fisheye", board=board)
    got = result.camera
    print(
        f"synthetic fisheye: render {len(photos)} photos {t_render:.2f} s; focal error "
        f"{100 * (got.fu / camera.fu - 1):+.3f}% / {100 * (got.fv / camera.fv - 1):+.3f}%, "
        f"principal point error {got.cu - camera.cu:+.3f} / {got.cv - camera.cv:+.3f} px"
    )


def bench_mounting(seeds: int) -> None:
    offset = np.array([0.06, -0.08])
    for lens in ("fisheye", "pinhole"):
        yaw_err, off_err, times = [], [], []
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            T = T_body_camera_upward(yaw=math.pi / 2, offset_xy=tuple(offset), height=0.32)
            camera = wide_angle_camera(lens, T_body_camera=T)  # type: ignore[arg-type]
            landmarks = _landmarks(rng)
            odo, pose, t_end = _drive()
            detections = _observations(camera, landmarks, pose, t_end, rng)
            t0 = time.perf_counter()
            r = mounting_from_observations(
                wide_angle_camera(lens),  # type: ignore[arg-type]
                landmarks,
                detections,
                odo,
                wheel_base_m=WHEEL_BASE,
            )
            times.append(time.perf_counter() - t0)
            yaw_err.append(math.degrees(r.yaw_rad) - 90.0)
            off_err.append(float(np.linalg.norm(r.offset_xy_m - offset)))
        ye, oe = np.abs(yaw_err), np.array(off_err) * 1000
        print(
            f"mounting {lens:8s} {seeds} seeds: yaw error max {ye.max():.3f} deg, RMS "
            f"{np.sqrt(np.mean(ye**2)):.3f} deg; offset error max {oe.max():.2f} mm, RMS "
            f"{np.sqrt(np.mean(oe**2)):.2f} mm; {1000 * np.median(times):.0f} ms per estimate "
            f"({len(detections)} frames)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    bench_lens()
    bench_synthetic_fisheye()
    bench_mounting(args.seeds)


if __name__ == "__main__":
    main()
