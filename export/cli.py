"""`irloc export REC --mcap OUT.mcap [--profile foxglove|ros2]`: a recording as MCAP.

REC is any recording folder: one written by `irloc simulate`, or one the server recorded
from a live robot (`<data dir>/recordings/<robot>-<time>/`). The poses are the ones the
robot's localizer gave live when the recording holds them (`live_poses.csv`, `--poses live`),
else the localizer runs over it as `irloc replay` does (`--poses replay`); everything is
written to one MCAP file: `--profile foxglove`
(default) with Foxglove's schemas, `--profile ros2` as a rosbag2 with ROS 2 messages in
CDR. The file is written under a temporary name and renamed when complete; errors are one
line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from export.content import export_content
from export.foxglove_mcap import write_foxglove
from export.poses_option import add_poses_option
from export.ros2_mcap import write_ros2
from export.topics import PROFILES, Profile
from recording.localize import PoseSource
from recording.reader import RecordingError, read_recording

PROG = "irloc export"


def export_recording(
    root: Path, out: Path, profile: Profile = "foxglove", poses: PoseSource | None = None
) -> dict[str, int]:
    """Write the MCAP of a recording; returns the message count per topic. `poses`: `replay`
    or `live` (None: `live` when the recording has them, `recording.localize.localized`).

    Raises:
        RecordingError: a malformed recording (file and line named).
        OSError: the output cannot be written.
    """
    rec = read_recording(root)
    content = export_content(rec, poses=poses)
    out.parent.mkdir(parents=True, exist_ok=True)
    if profile == "ros2":
        return write_ros2(content, out)
    tmp = out.with_name(f".{out.name}.part")
    try:
        counts = write_foxglove(content, tmp)
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    return counts


def main(argv: list[str] | None = None) -> int:
    """Entry point of `irloc export`; returns the exit status."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path, help="the recording folder")
    parser.add_argument("--mcap", type=Path, required=True, help="the MCAP file to write")
    parser.add_argument(
        "--profile",
        choices=PROFILES,
        default="foxglove",
        help="foxglove: Foxglove schemas (default); ros2: ROS 2 messages (rosbag2 in MCAP)",
    )
    add_poses_option(parser)
    parser.add_argument("--quiet", action="store_true", help="no summary")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    try:
        counts = export_recording(args.recording, args.mcap, args.profile, args.poses)
    except RecordingError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"{PROG}: {exc.filename or args.mcap}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    if not args.quiet:
        took = time.perf_counter() - start
        print(f"{PROG}: wrote {args.mcap} ({args.profile}) in {took:.1f} s")
        for topic, n in counts.items():
            print(f"  {topic:<30} {n:>7}")
    return 0
