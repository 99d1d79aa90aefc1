"""`irloc replay REC --out poses.csv`: run the localizer over a recording.

Reads the recording (docs/recording.md), feeds odometry, LED changes and
decoded frames to `localizer.Localizer` in time order (its LED requests are ignored: the LED
states come from `leds.csv`) and writes one row per listed frame:

    timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks

`x,y,theta` and the covariances are empty while there is no pose; `landmarks` lists the IDs
used in that frame, space-separated. A missing or unreadable frame is skipped with a warning
and counted (its row holds the odometry pose). A malformed file ends the run with one line
naming the file and line and exit status 1.

`--start-pose X,Y,THETA[,RADIUS]` (metres, radians, metres) tells the localizer where the
robot starts (a recording's own `start_pose.yaml` is used unless `--no-start-pose`);
`--config FILE` (YAML or JSON) sets detector and localizer settings. What the run used (every
setting and the start pose) is written beside the output as `<out stem>.settings.yaml`.

With ground truth (`--truth FILE`, by default `groundtruth.csv` beside the recording when
there is one) the run is scored and the Sec. V table printed (`recording.scoring`).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Literal, TextIO

from localizer.config import LocalizerConfig
from localizer.events import NoPose, PoseEstimate
from recording.layout import GROUNDTRUTH_FILE
from recording.localize import decode_threads, localize
from recording.poses_file import HEADER, format_row
from recording.reader import RecordingError, read_groundtruth_file, read_recording
from recording.scoring import error_stats, sec_v, sec_v_table, track_from_estimates
from recording.settings_file import read_config_file, write_settings_record
from recording.start_pose import StartPose, parse_start_pose

__all__ = ["HEADER", "decode_threads", "format_row", "main", "replay", "truth_summary"]
PROG = "irloc replay"


def replay(
    root: Path,
    out: TextIO,
    *,
    config: LocalizerConfig | None = None,
    warn: Callable[[str], None] = lambda _: None,
    progress: Callable[[int], Iterator[None]] | None = None,
    threads: int | None = None,
    estimates: list[PoseEstimate | NoPose] | None = None,
    start_pose: StartPose | Literal["recording"] | None = "recording",
) -> tuple[int, int]:
    """Localize a recording, writing rows to `out`.

    Args:
        root: the recording folder.
        out: where the CSV goes (the header is written first).
        config: localizer tuning.
        warn: called with a message for each skipped frame.
        progress: optional callback given the frame count, returning an iterator advanced
            once per frame (a progress bar).
        threads: PNG decoding threads (default `decode_threads()`), see `recording.localize`.
        estimates: when given, every frame's output is appended to it as well.
        start_pose: the prior on the start pose; "recording" (the default): the
            recording's `start_pose.yaml`, if any; None: none.

    Returns:
        (frames written, frames skipped).

    Raises:
        RecordingError: a malformed file, naming the file and line.
    """
    rec = read_recording(root)
    ticks = progress(len(rec.frames)) if progress is not None else None
    out.write(HEADER + "\n")
    written = skipped = 0
    prior = rec.start_pose if start_pose == "recording" else start_pose
    said = ""  # the passive identification's last decision, said when it changes
    for done in localize(rec, config=config, threads=threads, start_pose=prior):
        if done.why_not.split(":")[0] != said.split(":")[0]:
            if done.why_not:
                warn(f"frame {done.entry.t_ns}: no pose yet, {done.why_not}")
            said = done.why_not
        if done.image is None:
            skipped += 1
            warn(
                f"{done.entry.path}: missing or unreadable frame (cam0/data.csv:"
                f"{done.entry.line}), skipped"
            )
        out.write(format_row(done.estimate) + "\n")
        if estimates is not None:
            estimates.append(done.estimate)
        written += 1
        if ticks is not None:
            next(ticks, None)
    return written, skipped


def truth_summary(root: Path, truth: Path, estimates: list[PoseEstimate | NoPose]) -> str:
    """The Sec. V table of a replay against a ground-truth file (`recording.scoring`).

    Raises:
        RecordingError: a malformed ground-truth file.
    """
    t_gt, gt = read_groundtruth_file(truth)
    track = track_from_estimates(estimates)
    sweep_end = next((e.t_ns for e in read_recording(root).leds if e.all_lit), 0)
    result = sec_v(track, t_gt, gt, sweep_end_ns=sweep_end)
    return f"against {truth}\n" + sec_v_table(result, error_stats(track, t_gt, gt))


def _bar(total: int) -> Iterator[None]:
    from tqdm import tqdm

    with tqdm(total=total, unit="frame", desc="replay", file=sys.stderr) as bar:
        while True:
            bar.update(1)
            yield None


def main(argv: list[str] | None = None) -> int:
    """Entry point of `irloc replay`; returns the exit status."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path, help="the recording folder")
    parser.add_argument("--out", type=Path, required=True, help="poses.csv to write")
    parser.add_argument(
        "--quiet", action="store_true", help="no progress bar, warnings or table (only errors)"
    )
    parser.add_argument(
        "--truth",
        type=Path,
        default=None,
        help="ground truth (timestamp_ns,x,y,theta) to score against and print the Sec. V "
        "table; default groundtruth.csv beside the recording, when there is one",
    )
    parser.add_argument("--no-truth", action="store_true", help="do not score, even if present")
    parser.add_argument(
        "--start-pose",
        metavar="X,Y,THETA[,RADIUS]",
        default=None,
        help="where the robot starts: metres, radians (REP-103), and the search radius in "
        "metres (95 %% of the prior within it; default 1.2 m); overrides the recording's "
        "start_pose.yaml",
    )
    parser.add_argument(
        "--no-start-pose", action="store_true", help="ignore the recording's start_pose.yaml"
    )
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="detector and localizer settings (YAML or JSON; only what differs from the "
        "defaults, e.g. 'detection: {max_area_px: 1500}'); a replay's *.settings.yaml works too",
    )
    args = parser.parse_args(argv)
    prior: StartPose | Literal["recording"] | None = None if args.no_start_pose else "recording"
    if args.start_pose is not None:
        try:
            prior = parse_start_pose(args.start_pose)
        except ValueError as exc:
            print(f"{PROG}: --start-pose: {exc}", file=sys.stderr)
            return 2
    config = None
    if args.config is not None:
        try:
            config, _ = read_config_file(args.config)
        except RecordingError as exc:
            print(f"{PROG}: --config {exc}", file=sys.stderr)
            return 2
    truth = None if args.no_truth else args.truth
    if truth is None and not args.no_truth and (args.recording / GROUNDTRUTH_FILE).is_file():
        truth = args.recording / GROUNDTRUTH_FILE
    show = not args.quiet and sys.stderr.isatty()

    def warn(msg: str) -> None:
        if args.quiet:
            return
        if show:
            from tqdm import tqdm

            tqdm.write(f"{PROG}: warning: {msg}", file=sys.stderr)
        else:
            print(f"{PROG}: warning: {msg}", file=sys.stderr)

    start = time.perf_counter()
    estimates: list[PoseEstimate | NoPose] = []
    tmp = args.out.with_name(args.out.name + ".part")
    try:
        with tmp.open("w", encoding="utf-8", newline="\n") as f:
            written, skipped = replay(
                args.recording,
                f,
                config=config,
                warn=warn,
                progress=_bar if show else None,
                estimates=estimates,
                start_pose=prior,
            )
        tmp.replace(args.out)
        used = read_recording(args.recording).start_pose if prior == "recording" else prior
        source = (
            "none" if used is None else ("recording" if prior == "recording" else "command line")
        )
        write_settings_record(
            args.out,
            recording=args.recording,
            config=config or LocalizerConfig(),
            start_pose=used,
            start_pose_source=source,
            config_file=args.config,
        )
        table = None
        if truth is not None and not args.quiet:
            table = truth_summary(args.recording, truth, estimates)
    except RecordingError as exc:
        tmp.unlink(missing_ok=True)
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        print(f"{PROG}: {exc.filename or args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    if written and skipped == written:
        print(
            f"{PROG}: every frame of {args.recording} ({skipped}) is missing or unreadable: "
            f"nothing was localized ({args.out} has dead reckoning only)",
            file=sys.stderr,
        )
        return 1
    if not args.quiet:
        took = time.perf_counter() - start
        note = f", {skipped} unreadable frames skipped" if skipped else ""
        print(
            f"{PROG}: {written} poses written to {args.out} in {took:.1f} s{note}", file=sys.stderr
        )
    if table is not None:
        print(table)
    return 0
