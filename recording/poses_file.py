"""The localizer's poses as CSV: `irloc replay`'s output and a live recording's
`live_poses.csv` (the estimates the robot's localizer gave while it was recorded), one format.

Header `timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks,quality,deviation_m,reason`
(docs/recording.md): `x,y,theta` empty without a pose, the covariance's diagonal, the
landmark IDs used (space-separated), the pose's 0-1 quality, its 95 % radius (m, empty
without a pose) and the reason code when it is no landmark fix (docs/quality.md).
"""

from __future__ import annotations

from typing import get_args

import numpy as np

from localizer.events import Mode, NoPose, PoseEstimate
from recording.scoring import PoseTrack

HEADER = "timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks,quality,deviation_m,reason"
MODES: tuple[Mode, ...] = get_args(Mode)


def format_row(est: PoseEstimate | NoPose) -> str:
    """One CSV row (without the line end)."""
    reason = est.reason or ""
    if isinstance(est, NoPose):
        return f"{est.t_ns},,,,{est.mode},,,,,{est.quality:.3f},,{reason}"
    c = est.covariance
    ids = " ".join(str(i) for i in est.landmark_ids)
    quality = "" if est.quality is None else f"{est.quality:.3f}"
    deviation = "" if est.deviation_m is None else f"{est.deviation_m:.4f}"
    return (
        f"{est.t_ns},{est.x:.6f},{est.y:.6f},{est.theta:.7f},{est.mode},"
        f"{c[0, 0]:.3e},{c[1, 1]:.3e},{c[2, 2]:.3e},{ids},{quality},{deviation},{reason}"
    )


def estimates_from_track(track: PoseTrack, *, source: str) -> list[PoseEstimate | NoPose]:
    """The rows of a poses file (`recording.scoring.read_poses`) as localizer outputs: the
    covariance is the recorded diagonal (a missing entry is NaN).

    Raises:
        ValueError: a mode that is none of the localizer's, naming `source` and the row.
    """
    out: list[PoseEstimate | NoPose] = []
    for k, mode in enumerate(track.mode):
        if mode not in MODES:
            raise ValueError(f"{source}: row {k + 1}: unknown mode {mode!r}")
        m: Mode = MODES[MODES.index(mode)]
        t = int(track.t_ns[k])
        if not np.all(np.isfinite(track.pose[k])):
            out.append(NoPose(t, m))
            continue
        x, y, theta = (float(v) for v in track.pose[k])
        cov = np.diag(np.asarray(track.covariance_diag[k], dtype=np.float64))
        out.append(PoseEstimate(t, x, y, theta, cov, m, tuple(track.landmarks[k])))
    return out
