"""`irloc calibrate`: calibrate the lens from board photos and write the EuRoC sensor.yaml.

    irloc calibrate photos/*.jpg --pattern 9x6 --square 0.025 --model fisheye --out sensor.yaml
    irloc calibrate mounting RECORDING --out sensor.yaml      (see irloc.calibrate_mounting)

Nothing is written unless the calibration succeeds; errors are one line on stderr and a
non-zero exit status.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from calibration.atomic import write_atomic
from calibration.board import BoardSpec, parse_pattern
from calibration.lens import LENS_MODELS, LensCalibrationConfig
from calibration.uploads import calibrate_from_uploads, image_paths
from localizer.camera import camera_from_sensor


def _pattern(text: str) -> tuple[int, int]:
    try:
        return parse_pattern(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="irloc calibrate",
        description="Calibrate the upward camera's lens from photos of a chessboard or "
        "ChArUco board and write its EuRoC sensor.yaml. 'irloc calibrate mounting RECORDING "
        "--out sensor.yaml' measures the camera's mounting (T_BS) instead.",
    )
    p.add_argument("images", nargs="+", help="photos, or folders of photos")
    p.add_argument(
        "--pattern",
        type=_pattern,
        default=(9, 6),
        help="inner corners COLSxROWS (a board of 10x7 squares is 9x6; default 9x6)",
    )
    p.add_argument("--square", type=float, default=0.025, help="square side, metres")
    p.add_argument("--model", choices=LENS_MODELS, default="pinhole", help="lens model")
    p.add_argument(
        "--charuco",
        metavar="DICT",
        help="the board is a ChArUco board with this ArUco dictionary, e.g. DICT_5X5_100",
    )
    p.add_argument(
        "--marker", type=float, help="ChArUco marker side, metres (default 0.75 x square)"
    )
    p.add_argument("--min-views", type=int, default=5, help="fewest usable photos (default 5)")
    p.add_argument(
        "--mounting",
        type=Path,
        help="an existing sensor.yaml whose T_BS and rate_hz are kept (default: the reference "
        "upward mounting)",
    )
    p.add_argument("--rate", type=float, default=30.0, help="frame rate for sensor.yaml, Hz")
    p.add_argument("--out", type=Path, required=True, help="sensor.yaml to write")
    p.add_argument("--report", type=Path, help="also write the full report as JSON")
    return p


def _progress(total: int) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """A tqdm bar on a terminal, nothing otherwise."""
    if not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=total, desc="finding the board", unit="photo", file=sys.stderr)

    def update(done: int, _total: int) -> None:
        bar.n = done
        bar.refresh()

    return update, bar.close


def run(args: argparse.Namespace) -> str:
    """Calibrate and write the outputs; returns the summary. Raises ValueError on bad input."""
    options: dict[str, Any] = {"model": args.model, "rate_hz": args.rate}
    if args.min_views < 3:
        raise ValueError(f"--min-views must be at least 3, got {args.min_views}")
    options["config"] = LensCalibrationConfig(min_views=args.min_views)
    if args.charuco or args.marker is not None:
        options["board"] = BoardSpec(
            pattern=args.pattern,
            square_m=args.square,
            kind="charuco",
            marker_m=args.marker,
            dictionary=args.charuco or "DICT_5X5_100",
        )
    else:
        options["board"] = BoardSpec(pattern=args.pattern, square_m=args.square)
    if args.mounting is not None:
        try:
            data = yaml.safe_load(args.mounting.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as exc:
            raise ValueError(f"{args.mounting}: cannot read ({exc})") from None
        old = camera_from_sensor(data, source=str(args.mounting))
        options["T_body_camera"] = old.T_body_camera
        options["rate_hz"] = old.rate_hz
    paths = image_paths(args.images)
    files = []
    for path in paths:
        try:
            files.append((str(path), path.read_bytes()))
        except OSError as exc:
            raise ValueError(f"{path}: cannot read ({exc.strerror})") from None
    update, close = _progress(len(files))
    try:
        result = calibrate_from_uploads(files, progress=update, **options)
    finally:
        close()
    header = (
        f"# irloc calibrate: {result.model} lens, RMS {result.rms_px:.3f} px over "
        f"{result.used_views} views\n"
    )
    write_atomic(args.out, header + yaml.safe_dump(result.sensor(), sort_keys=False))
    if args.report is not None:
        write_atomic(args.report, json.dumps(result.to_dict(), indent=2) + "\n")
    return result.summary() + f"\n\nwrote {args.out}"


def main(argv: list[str]) -> int:
    """Entry point of `irloc calibrate`; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse has printed the usage and the error
        return int(exc.code or 0)
    try:
        summary = run(args)
    except ValueError as exc:
        print(f"irloc calibrate: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"irloc calibrate: error: cannot write: {exc}", file=sys.stderr)
        return 1
    print(summary)
    return 0
