"""Scoring a localizer's poses against a recording's ground truth, in the paper's terms.

Shared by `irloc replay --truth`, `irloc report` and the benchmarks (`bench/accuracy.py`,
`bench/bench_localizer.py`). Pure numpy on arrays; `read_poses` is the one reader (of the
`poses.csv` that `irloc replay` writes).

Sec. V of the paper measures the robot parked: at each stop of a 60 cm grid the position
error (mean 4.1 cm, std 2.9 cm, max 17.1 cm), the heading error while turning on the spot in
10 deg steps (mean 0.26 deg), and the jitter while parked (< 0.5 cm, < 0.3 deg). Here a stop
is a stretch where the ground truth does not move for `min_stop_s`; it is measured from
`settle_s` after the robot parked (and not before the identification sweep ended), the
error is that of the mean estimate over the stop, and the jitter is the largest deviation
of one estimate from that mean.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from localizer.events import NoPose, PoseEstimate
from localizer.geometry import wrap_angle
from localizer.types import BoolArray, FloatArray, IntArray

PAPER = {
    "mean_cm": 4.1,
    "std_cm": 2.9,
    "max_cm": 17.1,
    "heading_deg": 0.26,
    "jitter_cm": 0.5,
    "jitter_deg": 0.3,
}
"""The paper's Sec. V figures."""
SEC_V_LABELS = {
    "mean_cm": "mean position error, cm",
    "std_cm": "  std, cm",
    "max_cm": "max position error, cm",
    "heading_deg": "mean heading error, deg",
    "jitter_cm": "jitter, cm",
    "jitter_deg": "jitter, deg",
}
SETTLE_S = 0.25
MIN_STOP_S = 0.45


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """One localizer output per frame.

    Attributes:
        t_ns: frame times, shape (N,).
        pose: x, y (metres), theta (radians), NaN where there was no pose, shape (N, 3).
        mode: the localizer's mode per frame.
        landmarks: the landmark IDs used per frame.
        covariance_diag: var x, var y (m^2), var theta (rad^2), NaN without a pose, (N, 3).
    """

    t_ns: IntArray
    pose: FloatArray
    mode: tuple[str, ...]
    landmarks: tuple[tuple[int, ...], ...]
    covariance_diag: FloatArray

    @property
    def has_pose(self) -> BoolArray:
        return np.isfinite(self.pose[:, 0])


def track_from_estimates(estimates: Sequence[PoseEstimate | NoPose]) -> PoseTrack:
    """The track of a run of localizer outputs (one per frame)."""
    n = len(estimates)
    pose = np.full((n, 3), np.nan)
    cov = np.full((n, 3), np.nan)
    for k, e in enumerate(estimates):
        if isinstance(e, PoseEstimate):
            pose[k] = (e.x, e.y, e.theta)
            cov[k] = np.diag(e.covariance)
    return PoseTrack(
        np.array([e.t_ns for e in estimates], dtype=np.int64).reshape(-1),
        pose,
        tuple(e.mode for e in estimates),
        tuple(e.landmark_ids if isinstance(e, PoseEstimate) else () for e in estimates),
        cov,
    )


def read_poses(path: Path) -> PoseTrack:
    """A `poses.csv` of `irloc replay` (the covariance and landmark columns are optional).

    Raises:
        ValueError: a missing column or a value that is not a number, naming file and line.
    """
    with path.open(encoding="utf-8", newline="") as f:
        reader = csv.DictReader(f)
        missing = {"timestamp_ns", "x", "y", "theta", "mode"} - set(reader.fieldnames or ())
        if missing:
            raise ValueError(f"{path}:1: missing columns {sorted(missing)}")
        t, pose, cov, modes, ids = [], [], [], [], []
        for row in reader:
            try:
                t.append(int(row["timestamp_ns"]))
                pose.append([float(row[k]) if row[k] else np.nan for k in ("x", "y", "theta")])
                cov.append([float(row.get(k) or "nan") for k in ("cov_xx", "cov_yy", "cov_tt")])
                ids.append(tuple(int(i) for i in (row.get("landmarks") or "").split()))
            except ValueError as exc:
                raise ValueError(f"{path}:{reader.line_num}: {exc}") from None
            modes.append(row["mode"])
    return PoseTrack(
        np.array(t, dtype=np.int64),
        np.array(pose, dtype=np.float64).reshape(-1, 3),
        tuple(modes),
        tuple(ids),
        np.array(cov, dtype=np.float64).reshape(-1, 3),
    )


def truth_at(t_ns: npt.ArrayLike, t_gt: IntArray, gt: FloatArray) -> FloatArray:
    """The ground truth interpolated at `t_ns` (heading unwrapped, then wrapped), (N, 3)."""
    t = np.asarray(t_ns, dtype=np.float64)
    th = np.interp(t, t_gt, np.unwrap(gt[:, 2]))
    return np.column_stack(
        [np.interp(t, t_gt, gt[:, 0]), np.interp(t, t_gt, gt[:, 1]), wrap_angle(th)]
    )


def errors(track: PoseTrack, t_gt: IntArray, gt: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per frame: position error (m) and signed heading error (rad), NaN without a pose."""
    truth = truth_at(track.t_ns, t_gt, gt)
    pos = np.hypot(*(track.pose[:, :2] - truth[:, :2]).T)
    head = np.asarray(wrap_angle(track.pose[:, 2] - truth[:, 2]), dtype=np.float64)
    return pos, head


def error_stats(track: PoseTrack, t_gt: IntArray, gt: FloatArray) -> dict[str, float]:
    """Error statistics over every frame with a pose, and the share of frames per mode."""
    err, herr = errors(track, t_gt, gt)
    has = track.has_pose
    e, h = err[has], np.abs(herr[has])
    modes = np.array(track.mode)
    landmark = modes == "landmark"
    first = (track.t_ns[has][0] - track.t_ns[0]) * 1e-9 if has.any() else math.inf

    def pct(q: float) -> float:
        return float(np.percentile(e, q)) * 100 if len(e) else math.nan

    return {
        "frames": float(len(modes)),
        "posed": float(has.mean()) if len(has) else 0.0,
        "first_fix_s": float(first),
        "mean_cm": float(np.mean(e)) * 100 if len(e) else math.nan,
        "p50_cm": pct(50),
        "p95_cm": pct(95),
        "max_cm": float(np.max(e)) * 100 if len(e) else math.nan,
        "heading_mean_deg": float(np.degrees(np.mean(h))) if len(h) else math.nan,
        "heading_max_deg": float(np.degrees(np.max(h))) if len(h) else math.nan,
        "landmark": float(landmark.mean()) if len(modes) else 0.0,
        "dead_reckoning": float(np.mean(modes == "dead_reckoning")) if len(modes) else 0.0,
        "lost": float(np.mean(modes == "lost")) if len(modes) else 0.0,
        "fix_max_cm": float(np.max(err[landmark & has], initial=0.0)) * 100,
    }


def parked_stops(
    t_gt: IntArray, gt: FloatArray, min_s: float = MIN_STOP_S
) -> list[tuple[int, int]]:
    """(start, end) ground-truth index ranges where the pose stays the same >= min_s."""
    same = np.all(np.abs(np.diff(gt, axis=0)) < 1e-9, axis=1)
    out, i = [], 0
    while i < len(same):
        if same[i]:
            j = i
            while j < len(same) and same[j]:
                j += 1
            if (t_gt[j] - t_gt[i]) * 1e-9 >= min_s:
                out.append((i, j + 1))
            i = j
        else:
            i += 1
    return out


@dataclass(frozen=True)
class StopScore:
    """One parked stop.

    Attributes:
        t0_ns, t1_ns: the measured window.
        true: the true pose (x, y, theta), shape (3,).
        mean: the mean estimate (x, y, and theta as true theta + mean heading error), (3,).
        position_error_m: distance of the mean estimate from the truth.
        heading_error_rad: the mean heading error (signed).
        jitter_m, jitter_rad: largest deviation of one estimate from the stop's mean.
        frames: estimates in the window.
    """

    t0_ns: int
    t1_ns: int
    true: FloatArray
    mean: FloatArray
    position_error_m: float
    heading_error_rad: float
    jitter_m: float
    jitter_rad: float
    frames: int


@dataclass(frozen=True)
class SecV:
    """Sec. V figures of one run.

    Attributes:
        stops: per parked stop.
        figures: mean_cm, std_cm, max_cm, heading_deg, jitter_cm, jitter_deg (keys of `PAPER`)
            and stops; NaN when no stop could be measured.
        startup_cm: how far the output moved from the first fix until the first window.
        sweep_end_s: when the identification sweep ended (all LEDs lit).
    """

    stops: tuple[StopScore, ...]
    figures: dict[str, float]
    startup_cm: float
    sweep_end_s: float


def sec_v(
    track: PoseTrack,
    t_gt: IntArray,
    gt: FloatArray,
    *,
    sweep_end_ns: int = 0,
    settle_s: float = SETTLE_S,
    frame: tuple[float, FloatArray] | None = None,
) -> SecV:
    """Per-stop errors and jitter, the paper's way.

    Args:
        track: the localizer's output.
        t_gt, gt: ground truth times (N,) and poses (N, 3).
        sweep_end_ns: the end of the identification sweep; stops are measured from
            `settle_s` after it.
        settle_s: a stop's window starts this long after the robot parked.
        frame: (rotation rad, translation (2,)) taking true positions into the surveyed
            map's frame; when given, the errors are measured in that frame.
    """
    ref = gt.copy()
    if frame is not None:
        c, s = math.cos(frame[0]), math.sin(frame[0])
        ref[:, :2] = gt[:, :2] @ np.array([[c, -s], [s, c]]).T + frame[1]
        ref[:, 2] = gt[:, 2] + frame[0]
    has = track.has_pose
    t, est = track.t_ns[has], track.pose[has]
    stops: list[StopScore] = []
    startup_cm = 0.0
    for a, b in parked_stops(t_gt, gt):
        start = max(int(t_gt[a]), sweep_end_ns) + int(settle_s * 1e9)
        sel = (t >= start) & (t <= t_gt[b - 1] - int(0.05e9))
        if np.count_nonzero(sel) < 5:
            continue
        e = est[sel]
        mean_xy = e[:, :2].mean(axis=0)
        dth = np.asarray(wrap_angle(e[:, 2] - ref[a, 2]), dtype=np.float64)
        stops.append(
            StopScore(
                t0_ns=start,
                t1_ns=int(t_gt[b - 1]),
                true=ref[a].copy(),
                mean=np.array([mean_xy[0], mean_xy[1], float(wrap_angle(ref[a, 2] + dth.mean()))]),
                position_error_m=float(np.hypot(*(mean_xy - ref[a, :2]))),
                heading_error_rad=float(dth.mean()),
                jitter_m=float(np.max(np.hypot(*(e[:, :2] - mean_xy).T))),
                jitter_rad=float(np.max(np.abs(dth - dth.mean()))),
                frames=int(np.count_nonzero(sel)),
            )
        )
        if t_gt[a] < sweep_end_ns and len(t):  # the start-up: from the first fix to the window
            early = t < start
            if early.any():
                startup_cm = float(np.max(np.hypot(*(est[early, :2] - mean_xy).T))) * 100
    return SecV(tuple(stops), sec_v_figures(stops), startup_cm, sweep_end_ns * 1e-9)


def sec_v_figures(stops: Sequence[StopScore]) -> dict[str, float]:
    """The paper's figures (keys of `PAPER`, plus `stops`) over the stops."""
    if not stops:
        return {k: math.nan for k in PAPER} | {"stops": 0.0}
    p = np.array([s.position_error_m for s in stops]) * 100
    return {
        "stops": float(len(stops)),
        "mean_cm": float(p.mean()),
        "std_cm": float(p.std()),
        "max_cm": float(p.max()),
        "heading_deg": float(np.degrees(np.mean([abs(s.heading_error_rad) for s in stops]))),
        "jitter_cm": float(max(s.jitter_m for s in stops)) * 100,
        "jitter_deg": float(np.degrees(max(s.jitter_rad for s in stops))),
    }


def sec_v_table(result: SecV, stats: dict[str, float] | None = None) -> str:
    """The Sec. V table beside the paper's, and (with `stats` of `error_stats`) every frame's
    errors and the share of frames per mode, as plain text."""
    f = result.figures
    lines = [
        f"Sec. V figures over {int(f['stops'])} parked stops",
        f"  {'':<26}{'irloc':>10}{'paper':>10}",
    ]
    lines += [f"  {label:<26}{f[k]:>10.3f}{PAPER[k]:>10.2f}" for k, label in SEC_V_LABELS.items()]
    if stats is not None:
        lines += [
            f"every frame with a pose ({100 * stats['posed']:.1f} % of {int(stats['frames'])}): "
            f"position error mean {stats['mean_cm']:.2f} cm, p95 {stats['p95_cm']:.2f} cm, "
            f"max {stats['max_cm']:.2f} cm; heading error mean {stats['heading_mean_deg']:.3f}"
            f" deg, max {stats['heading_max_deg']:.3f} deg",
            f"modes: landmark {100 * stats['landmark']:.1f} %, dead reckoning "
            f"{100 * stats['dead_reckoning']:.1f} %, lost {100 * stats['lost']:.1f} %; "
            f"first fix after {stats['first_fix_s']:.2f} s",
        ]
    return "\n".join(lines)


def odometry_stops(
    t_ns: IntArray, v: FloatArray, min_s: float = MIN_STOP_S, still_m_s: float = 1e-4
) -> list[tuple[int, int]]:
    """(start, end) times (ns) where both wheel speeds stay below `still_m_s` for `min_s` or
    longer: where a recording without ground truth is parked."""
    still = np.all(np.abs(v) < still_m_s, axis=1) if len(v) else np.zeros(0, dtype=bool)
    out: list[tuple[int, int]] = []
    i = 0
    while i < len(still):
        if still[i]:
            j = i
            while j + 1 < len(still) and still[j + 1]:
                j += 1
            if (t_ns[j] - t_ns[i]) * 1e-9 >= min_s:
                out.append((int(t_ns[i]), int(t_ns[j])))
            i = j + 1
        else:
            i += 1
    return out


def jitter_while_parked(
    track: PoseTrack, windows: Sequence[tuple[int, int]], settle_s: float = SETTLE_S
) -> list[tuple[int, int, float, float]]:
    """Per parked window (t0, t1 ns) with 5 or more poses from `settle_s` after t0: (t0, t1,
    largest deviation of one position from the window's mean (m), the same of the heading
    (rad))."""
    has = track.has_pose
    t, est = track.t_ns[has], track.pose[has]
    out = []
    for t0, t1 in windows:
        sel = (t >= t0 + int(settle_s * 1e9)) & (t <= t1)
        if np.count_nonzero(sel) < 5:
            continue
        e = est[sel]
        mean = e[:, :2].mean(axis=0)
        dth = np.unwrap(e[:, 2])
        out.append(
            (
                int(t0),
                int(t1),
                float(np.max(np.hypot(*(e[:, :2] - mean).T))),
                float(np.max(np.abs(dth - dth.mean()))),
            )
        )
    return out
