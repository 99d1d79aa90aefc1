"""`irloc report REC [--truth groundtruth.csv] --out report.html`: the validation report.

Runs the localizer over the recording and writes one self-contained HTML file in the paper's
format (Sec. V figures beside the paper's, Fig. 9 and Fig. 10 style plots, error over time by
mode, jitter while parked, landmarks used, per-frame processing time); the Sec. V table is
also printed. Errors are one line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from export.poses_option import add_poses_option
from export.report import write_report
from recording.reader import RecordingError
from recording.scoring import sec_v_table

PROG = "irloc report"


def main(argv: list[str] | None = None) -> int:
    """Entry point of `irloc report`; returns the exit status."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path, help="the recording folder")
    parser.add_argument("--out", type=Path, required=True, help="report.html to write")
    parser.add_argument(
        "--truth",
        type=Path,
        default=None,
        help="ground truth CSV (timestamp_ns,x,y,theta); default groundtruth.csv beside the "
        "recording, when there is one",
    )
    add_poses_option(parser)
    parser.add_argument("--quiet", action="store_true", help="print nothing on success")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    try:
        data = write_report(args.recording, args.out, args.truth, poses=args.poses)
    except RecordingError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"{PROG}: {exc.filename or args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    if not args.quiet:
        if data.result is not None:
            print(sec_v_table(data.result, data.stats))
        print(f"{PROG}: wrote {args.out} in {time.perf_counter() - start:.1f} s")
    return 0
