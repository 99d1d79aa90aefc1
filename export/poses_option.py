"""The `--poses live|replay` option that `irloc export` and `irloc report` share."""

from __future__ import annotations

import argparse


def add_poses_option(parser: argparse.ArgumentParser) -> None:
    """Add `--poses` (default None: live when the recording holds them, else replay)."""
    parser.add_argument(
        "--poses",
        choices=("live", "replay"),
        default=None,
        help="live: what the robot's localizer gave (a live recording's live_poses.csv); "
        "replay: run the localizer over the recording; default live when recorded",
    )
