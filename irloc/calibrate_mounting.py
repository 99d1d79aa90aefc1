"""`irloc calibrate mounting RECORDING --out sensor.yaml`: the mounting from a recording.

The recording (docs/recording.md) must hold, in this order: the start-up
identification sweep (one landmark lit at a time, robot standing still), then a turn in
place and a straight drive with the landmarks lit. Its `cam0/sensor.yaml` gives the lens;
its `T_BS` is what gets replaced.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from bisect import bisect_right
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from calibration.atomic import write_atomic
from calibration.identify import identify_spots
from calibration.mounting import MountingCalibration, mounting_from_observations
from localizer.camera import sensor_from_camera
from localizer.spots import DetectionConfig, detect_spots
from localizer.types import FloatArray
from recording.reader import Recording, read_recording


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="irloc calibrate mounting",
        description="Measure the camera's mounting (T_BS) from a recording of the start-up "
        "sweep, a turn in place and a straight drive under known landmarks.",
    )
    p.add_argument("recording", type=Path, help="recording folder")
    p.add_argument("--out", type=Path, required=True, help="sensor.yaml to write (new T_BS)")
    p.add_argument("--report", type=Path, help="also write the result as JSON")
    return p


def _frames(rec: Recording) -> Iterator[tuple[int, FloatArray, frozenset[int] | None]]:
    """(t_ns, spot pixels, lit ids or None) per frame, decoding and detecting as it goes."""
    led_times = [e.t_ns for e in rec.leds]
    config = DetectionConfig()
    for entry in rec.frames:
        decoded = cv2.imread(str(entry.path), cv2.IMREAD_GRAYSCALE)
        if decoded is None:
            raise ValueError(
                f"{entry.path}: cannot read the frame (cam0/data.csv line {entry.line})"
            )
        image = np.asarray(decoded, dtype=np.uint8)
        k = bisect_right(led_times, entry.t_ns) - 1
        lit = None if k < 0 or rec.leds[k].all_lit else rec.leds[k].lit
        yield entry.t_ns, detect_spots(image, config).pixels, lit


def calibrate_recording(root: Path) -> tuple[Recording, MountingCalibration]:
    """Identify the landmarks of every frame and estimate the mounting; ValueError on bad data."""
    rec = read_recording(root)
    detections = identify_spots(rec.camera, rec.landmark_map, _frames(rec))
    odometry = [
        (int(t), float(v[0]), float(v[1])) for t, v in zip(rec.odom_t_ns, rec.odom_v, strict=True)
    ]
    result = mounting_from_observations(
        rec.camera, rec.landmark_map, detections, odometry, wheel_base_m=rec.robot.wheel_base
    )
    return rec, result


def summary(result: MountingCalibration) -> str:
    d: dict[str, Any] = result.to_dict()
    return "\n".join(
        [
            f"yaw: {d['yaw_deg']:.3f} deg +- {d['yaw_std_deg']:.3f}",
            "offset x, y: {:.4f}, {:.4f} m +- {:.4f}, {:.4f}".format(
                *result.offset_xy_m, *result.offset_std_m
            ),
            f"height: {result.height_m:.4f} m",
            f"frames: {result.frames_turn} turning, {result.frames_straight} straight, "
            f"{result.frames_dropped} dropped",
            f"residuals: circle {1000 * d['circle_rms_m']:.1f} mm RMS, "
            f"line {1000 * d['line_rms_m']:.1f} mm RMS",
            f"turn: camera {d['turn_angle_camera_deg']:.2f} deg, "
            f"odometry {d['turn_angle_odometry_deg']:.2f} deg",
        ]
    )


def main(argv: list[str]) -> int:
    """Entry point of `irloc calibrate mounting`; returns the exit status."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        rec, result = calibrate_recording(args.recording)
        camera = dataclasses.replace(rec.camera, T_body_camera=result.T_body_camera)
        text = yaml.safe_dump(sensor_from_camera(camera), sort_keys=False)
        write_atomic(args.out, "# irloc calibrate mounting\n" + text)
        if args.report is not None:
            write_atomic(args.report, json.dumps(result.to_dict(), indent=2) + "\n")
    except (ValueError, OSError) as exc:
        print(f"irloc calibrate mounting: error: {exc}", file=sys.stderr)
        return 1
    print(summary(result) + f"\n\nwrote {args.out}")
    return 0
