"""The validation report of a recording, in the paper's format (Sec. V): one self-contained
HTML file (CSS inline, figures as base64 PNGs), no network needed to view it.

The localizer runs over the recording (`recording.localize`, as `irloc replay`); with ground
truth (`--truth FILE`, default `groundtruth.csv` beside the recording) it is scored the
paper's way (`recording.scoring.sec_v`: parked stops, position and heading error, jitter)
and the table stands beside the paper's figures. Without ground truth the report keeps what
needs none: modes, landmarks used, jitter while parked (parked = both wheels still), and
the per-frame processing time.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from export import report_plots as plots
from localizer.events import NoPose, PoseEstimate
from localizer.types import FloatArray, IntArray
from recording.layout import GROUNDTRUTH_FILE
from recording.localize import PoseSource, localized, pose_source
from recording.reader import Recording, read_groundtruth_file, read_recording
from recording.scoring import (
    PAPER,
    SEC_V_LABELS,
    PoseTrack,
    SecV,
    error_stats,
    errors,
    jitter_while_parked,
    odometry_stops,
    sec_v,
    track_from_estimates,
)


@dataclass(frozen=True, eq=False)
class ReportData:
    """What the report shows.

    Attributes:
        recording: the recording.
        track: the localizer's output per frame.
        cpu_s: per-frame CPU time of the localizer, seconds, shape (N,).
        truth: (t_ns, poses (M, 3)) or None; truth_source: its file.
        result: the Sec. V scoring (None without truth).
        stats: `error_stats` (None without truth).
        jitters: per parked stop (t0, t1, jitter m, jitter rad).
        poses: where the poses come from: `replay` (the localizer run over the recording) or
            `live` (what the robot's localizer gave, `live_poses.csv`; no CPU times then).
    """

    recording: Recording
    track: PoseTrack
    cpu_s: FloatArray
    truth: tuple[IntArray, FloatArray] | None
    truth_source: Path | None
    result: SecV | None
    stats: dict[str, float] | None
    jitters: list[tuple[int, int, float, float]]
    poses: PoseSource = "replay"


def collect(
    root: Path,
    truth: Path | None = None,
    *,
    use_truth: bool = True,
    poses: PoseSource | None = None,
) -> ReportData:
    """Localize the recording (or read its live poses) and score it.

    Args:
        root: the recording folder.
        truth: a ground-truth CSV; default `groundtruth.csv` beside the recording if present.
        use_truth: False ignores any ground truth.
        poses: `replay` or `live` (`recording.localize.localized`); None: `live` when the
            recording has them.

    Raises:
        RecordingError: a malformed recording or ground-truth file.
    """
    rec = read_recording(root)
    if truth is None and use_truth and (Path(root) / GROUNDTRUTH_FILE).is_file():
        truth = Path(root) / GROUNDTRUTH_FILE
    gt = read_groundtruth_file(truth) if (truth is not None and use_truth) else None
    estimates: list[PoseEstimate | NoPose] = []
    cpu: list[float] = []
    source = pose_source(rec, poses)
    for done in localized(rec, source):
        estimates.append(done.estimate)
        if source == "replay":
            cpu.append(done.cpu_s)
    track = track_from_estimates(estimates)
    result = stats = None
    if gt is not None:
        sweep_end = next((e.t_ns for e in rec.leds if e.all_lit), 0)
        result = sec_v(track, gt[0], gt[1], sweep_end_ns=sweep_end)
        stats = error_stats(track, gt[0], gt[1])
        jitters = [(s.t0_ns, s.t1_ns, s.jitter_m, s.jitter_rad) for s in result.stops]
    else:
        jitters = jitter_while_parked(track, odometry_stops(rec.odom_t_ns, rec.odom_v))
    return ReportData(
        rec,
        track,
        np.array(cpu),
        gt,
        truth if gt is not None else None,
        result,
        stats,
        jitters,
        source,
    )


def _fmt(v: float, digits: int = 3) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{digits}f}"


def _sec_v_rows(result: SecV) -> str:
    rows = []
    for key, label in SEC_V_LABELS.items():
        ours, paper = result.figures[key], PAPER[key]
        better = math.isfinite(ours) and ours <= paper
        mark = '<span class="ok">&#10003;</span>' if better else '<span class="bad">&#10007;</span>'
        rows.append(
            f"<tr><td>{html.escape(label.strip())}</td><td class=n>{_fmt(ours)}</td>"
            f"<td class=n>{paper:.2f}</td><td>{mark}</td></tr>"
        )
    return "\n".join(rows)


def _facts(data: ReportData) -> list[tuple[str, str]]:
    rec, track = data.recording, data.track
    cam = rec.camera
    t = track.t_ns
    span = (t[-1] - t[0]) * 1e-9 if len(t) else 0.0
    modes = np.array(track.mode)
    ms = data.cpu_s * 1000
    facts = [
        ("recording", str(rec.root)),
        ("frames", f"{len(t)} over {span:.1f} s"),
        (
            "poses",
            "live: what the robot's localizer gave (live_poses.csv)"
            if data.poses == "live"
            else "replay: the localizer run over the recording",
        ),
        ("camera", f"{cam.width}x{cam.height}, {cam.distortion_model}, {cam.rate_hz:g} Hz"),
        ("landmarks in the map", str(len(rec.landmark_map.ids))),
        ("frames with a pose", f"{100 * float(track.has_pose.mean()) if len(t) else 0:.1f} %"),
        (
            "modes",
            ", ".join(
                f"{m} {100 * float(np.mean(modes == m)):.1f} %"
                for m in ("landmark", "dead_reckoning", "identifying", "lost")
            ),
        ),
        (
            "per-frame time",
            f"median {np.median(ms):.2f} ms, p99 {np.percentile(ms, 99):.2f} ms"
            if len(ms)
            else "- (not recorded live)"
            if data.poses == "live"
            else "-",
        ),
        ("ground truth", str(data.truth_source) if data.truth_source else "none"),
    ]
    return facts


def render_html(data: ReportData) -> str:
    """The report as one self-contained HTML document."""
    rec, track = data.recording, data.track
    lm = rec.landmark_map
    ids = [int(i) for i in lm.ids]
    t_s = (track.t_ns - track.t_ns[0]) * 1e-9 if len(track.t_ns) else np.zeros(0)
    figures: list[tuple[str, str]] = []
    stops = list(data.result.stops) if data.result else []
    truth_xy = data.truth[1][:, :2] if data.truth else None
    figures.append(
        (
            plots.png_data_uri(
                plots.floor_figure(
                    ids, lm.positions, stops, truth_xy, track.pose[track.has_pose][:, :2]
                )
            ),
            "Estimated (circles) and true (asterisks) positions at each parked stop, the mean "
            "estimate over the stop (paper Fig. 9); right: each stop's error as an arrow.",
        )
    )
    if data.truth is not None:
        figures.append(
            (
                plots.png_data_uri(plots.heading_figure(stops)),
                "Mean heading error at each parked stop against the true heading "
                "(paper Fig. 10: the sensor turned in 10 deg steps).",
            )
        )
        pos, head = errors(track, data.truth[0], data.truth[1])
        figures.append(
            (
                plots.png_data_uri(plots.error_time_figure(t_s, pos, head, track.mode)),
                "Every frame's error against the ground truth, coloured by the localizer's mode.",
            )
        )
    if data.jitters:
        figures.append(
            (
                plots.png_data_uri(plots.jitter_figure(data.jitters)),
                "Largest deviation of one estimate from the stop's mean, per parked "
                "stop (log scale; the paper: below 0.5 cm and 0.3 deg).",
            )
        )
    figures.append(
        (
            plots.png_data_uri(plots.landmarks_figure(track, ids)),
            "The landmarks whose spots each frame's pose used (green) and their number (grey).",
        )
    )
    if len(data.cpu_s):
        figures.append(
            (
                plots.png_data_uri(plots.timing_figure(data.cpu_s, track.mode)),
                "Per-frame processing time: the CPU time of the localizer's thread "
                "for each frame (and the odometry since the previous one).",
            )
        )
    facts = "\n".join(
        f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in _facts(data)
    )
    table = ""
    if data.result is not None and data.stats is not None:
        s = data.stats
        table = f"""
<h2>Sec. V figures over {int(data.result.figures["stops"])} parked stops</h2>
<table class="secv"><tr><th></th><th>irloc</th><th>paper</th><th></th></tr>
{_sec_v_rows(data.result)}
</table>
<p class="note">Every frame with a pose: position error mean {_fmt(s["mean_cm"], 2)} cm,
p95 {_fmt(s["p95_cm"], 2)} cm, max {_fmt(s["max_cm"], 2)} cm; heading error mean
{_fmt(s["heading_mean_deg"])} deg, max {_fmt(s["heading_max_deg"])} deg; first fix after
{_fmt(s["first_fix_s"], 2)} s. A stop is a stretch where the ground truth stays still for
0.45 s or more, measured from 0.25 s after the robot parked (and after the identification
sweep); its error is that of the mean estimate, its jitter the largest deviation from that
mean. Start-up: the output moved {_fmt(data.result.startup_cm)} cm from the first fix until
the first measured window.</p>"""
    else:
        table = (
            "<p class=note>No ground truth: errors cannot be measured. Jitter is measured "
            "where both wheels stood still.</p>"
        )
    body = "\n".join(
        f'<figure><img src="{uri}" alt=""><figcaption>{html.escape(cap)}</figcaption></figure>'
        for uri, cap in figures
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>irloc validation report: {html.escape(rec.root.name)}</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1180px; margin: 24px auto; color: #222; }}
h1 {{ font-size: 22px; margin-bottom: 4px; }} h2 {{ font-size: 17px; margin: 18px 0 6px; }}
.top {{ display: flex; gap: 28px; align-items: flex-start; }}
table {{ border-collapse: collapse; font-size: 14px; }}
th, td {{ padding: 3px 10px; border-bottom: 1px solid #e3e3e3; text-align: left; }}
td.n {{ text-align: right; font-variant-numeric: tabular-nums; }}
.secv th {{ background: #f3f5f8; }} .ok {{ color: #2a9d3f; }} .bad {{ color: #c0392b; }}
.note {{ font-size: 13px; color: #555; max-width: 1100px; }}
figure {{ margin: 14px 0; }} img {{ max-width: 100%; }}
figcaption {{ font-size: 13px; color: #555; }}
</style></head><body>
<h1>irloc validation report: {html.escape(rec.root.name)}</h1>
<p class="note">Sohn et al., Sec. V: position error at the points of a 60 cm grid, heading
error while turning on the spot, jitter while parked. Produced by <code>irloc report</code>.</p>
<div class="top"><div><h2>Run</h2><table>{facts}</table></div><div>{table}</div></div>
{body}
</body></html>
"""


def write_report(
    root: Path, out: Path, truth: Path | None = None, *, poses: PoseSource | None = None
) -> ReportData:
    """Collect, render and write the report (via a temporary file, then renamed)."""
    data = collect(root, truth, poses=poses)
    text = render_html(data)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.part")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(out)
    return data
