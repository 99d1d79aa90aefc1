"""The report's figures (matplotlib, object API: no pyplot state, no display), each embedded
in the HTML as a base64 PNG by `png_data_uri`."""

from __future__ import annotations

import base64
import io
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from localizer.types import FloatArray
from recording.scoring import PAPER, PoseTrack, StopScore

MODE_COLOURS = {
    "landmark": "#2a9d3f",
    "dead_reckoning": "#e08a00",
    "identifying": "#6c6cd0",
    "lost": "#c0392b",
}


def png_data_uri(fig: Figure, dpi: int = 110) -> str:
    """The figure as a `data:image/png;base64,...` URI."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def floor_figure(
    landmark_ids: Sequence[int],
    landmarks: FloatArray,
    stops: Sequence[StopScore],
    truth_path: FloatArray | None,
    estimate_path: FloatArray,
) -> Figure:
    """Fig. 9: estimated (circles) and true (asterisks) positions at the parked stops, on
    the floor, with the landmarks; beside it each stop's error as a magnified arrow."""
    fig = Figure(figsize=(10.5, 4.6))
    ax, ax_err = fig.subplots(1, 2)
    for a in (ax, ax_err):
        a.scatter(
            landmarks[:, 0],
            landmarks[:, 1],
            marker="^",
            s=70,
            c="#d4a20a",
            edgecolors="k",
            zorder=3,
            label="landmark",
        )
        for i, p in zip(landmark_ids, landmarks, strict=True):
            a.annotate(str(i), (p[0], p[1]), xytext=(5, 5), textcoords="offset points")
        a.set_aspect("equal")
        a.set_xlabel("x (m)")
        a.set_ylabel("y (m)")
        a.grid(alpha=0.3)
    if truth_path is not None:
        ax.plot(truth_path[:, 0], truth_path[:, 1], color="0.75", lw=0.8, label="true path")
    ax.plot(
        estimate_path[:, 0],
        estimate_path[:, 1],
        color="#7fb3e0",
        lw=0.6,
        alpha=0.8,
        label="estimated path",
    )
    if stops:
        true = np.array([s.true[:2] for s in stops])
        est = np.array([s.mean[:2] for s in stops])
        ax.scatter(true[:, 0], true[:, 1], marker="*", s=70, c="k", zorder=4, label="true")
        ax.scatter(
            est[:, 0],
            est[:, 1],
            marker="o",
            s=60,
            facecolors="none",
            edgecolors="#1f5fbf",
            lw=1.3,
            zorder=5,
            label="estimated",
        )
        err = est - true
        scale = _arrow_scale(err, np.vstack([true, landmarks[:, :2]]))
        ax_err.quiver(
            true[:, 0],
            true[:, 1],
            err[:, 0] * scale,
            err[:, 1] * scale,
            angles="xy",
            scale_units="xy",
            scale=1,
            color="#c0392b",
            width=0.004,
        )
        ax_err.scatter(true[:, 0], true[:, 1], marker="*", s=40, c="k", zorder=4)
        tips = np.vstack([true + err * scale, true, landmarks[:, :2]])
        pad = 0.08 * max(float(np.ptp(tips, axis=0).max()), 0.5)
        ax_err.set_xlim(tips[:, 0].min() - pad, tips[:, 0].max() + pad)
        ax_err.set_ylim(tips[:, 1].min() - pad, tips[:, 1].max() + pad)
        ax_err.set_title(f"error at each stop, magnified {scale:.0f}x")
    ax.set_title("estimated vs true positions at the parked stops (Fig. 9)")
    fig.legend(
        *ax.get_legend_handles_labels(),
        fontsize=8,
        loc="lower center",
        ncol=5,
        bbox_to_anchor=(0.5, -0.04),
    )
    return fig


def _arrow_scale(err: FloatArray, points: FloatArray) -> float:
    """A round magnification (1, 2 or 5 times a power of ten) that draws the median error
    arrow about 1/8 of the plot's extent long."""
    extent = float(np.ptp(points, axis=0).max()) if len(points) > 1 else 1.0
    typical = float(np.median(np.hypot(err[:, 0], err[:, 1]))) if len(err) else 0.0
    if typical <= 0:
        return 1.0
    raw = max(extent, 0.5) / 8 / typical
    decade = 10 ** np.floor(np.log10(raw))
    return float(decade * max(m for m in (1, 2, 5) if m * decade <= raw))


def heading_figure(stops: Sequence[StopScore]) -> Figure:
    """Fig. 10: heading error against heading at each parked stop."""
    fig = Figure(figsize=(10.5, 3.4))
    ax = fig.subplots()
    if stops:
        heading = np.degrees(np.mod([s.true[2] for s in stops], 2 * np.pi))
        err = np.degrees([s.heading_error_rad for s in stops])
        order = np.argsort(heading)
        ax.plot(heading[order], err[order], "o-", ms=4, lw=0.8, color="#1f5fbf", label="irloc")
    for sign in (1, -1):
        ax.axhline(
            sign * PAPER["heading_deg"],
            color="#c0392b",
            ls="--",
            lw=0.8,
            label="paper mean |error| 0.26 deg" if sign > 0 else None,
        )
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xlim(0, 360)
    ax.set_xticks(range(0, 361, 30))
    ax.set_xlabel("true heading (deg)")
    ax.set_ylabel("heading error (deg)")
    ax.set_title("heading error against heading, parked (Fig. 10)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")  # not "best": slow on many points
    return fig


def error_time_figure(
    t_s: FloatArray, pos_err_m: FloatArray, head_err_rad: FloatArray, modes: Sequence[str]
) -> Figure:
    """Position and heading error of every frame over time, coloured by the mode."""
    fig = Figure(figsize=(10.5, 4.4))
    ax_p, ax_h = fig.subplots(2, 1, sharex=True)
    m = np.array(modes)
    for mode, colour in MODE_COLOURS.items():
        sel = (m == mode) & np.isfinite(pos_err_m)
        if sel.any():
            ax_p.scatter(t_s[sel], pos_err_m[sel] * 100, s=3, c=colour, label=mode)
            ax_h.scatter(t_s[sel], np.degrees(head_err_rad[sel]), s=3, c=colour)
    ax_p.set_ylabel("position error (cm)")
    ax_h.set_ylabel("heading error (deg)")
    ax_h.set_xlabel("time (s)")
    ax_p.set_title("error over time, coloured by mode")
    ax_p.legend(fontsize=8, markerscale=3, loc="upper right")
    for a in (ax_p, ax_h):
        a.grid(alpha=0.3)
    return fig


def jitter_figure(jitters: Sequence[tuple[int, int, float, float]]) -> Figure:
    """Per parked stop: the largest deviation from the stop's mean, position and heading."""
    fig = Figure(figsize=(10.5, 3.0))
    ax_p, ax_h = fig.subplots(1, 2)
    k = np.arange(len(jitters))
    ax_p.bar(k, [j[2] * 100 for j in jitters], color="#1f5fbf")
    ax_h.bar(k, [np.degrees(j[3]) for j in jitters], color="#1f5fbf")
    ax_p.axhline(PAPER["jitter_cm"], color="#c0392b", ls="--", lw=0.8, label="paper < 0.5 cm")
    ax_h.axhline(PAPER["jitter_deg"], color="#c0392b", ls="--", lw=0.8, label="paper < 0.3 deg")
    ax_p.set_ylabel("position jitter (cm)")
    ax_h.set_ylabel("heading jitter (deg)")
    for a in (ax_p, ax_h):
        a.set_xlabel("parked stop")
        a.set_yscale("log")
        a.legend(fontsize=8, loc="upper right")
        a.grid(alpha=0.3, which="both")
    fig.suptitle("jitter while parked")
    return fig


def landmarks_figure(track: PoseTrack, landmark_ids: Sequence[int]) -> Figure:
    """Which landmarks each frame's pose used, and how many."""
    fig = Figure(figsize=(10.5, 3.2))
    ax = fig.subplots()
    t = (track.t_ns - track.t_ns[0]) * 1e-9 if len(track.t_ns) else np.zeros(0)
    rows = {int(i): k for k, i in enumerate(landmark_ids)}
    xs, ys = [], []
    for tk, used in zip(t, track.landmarks, strict=True):
        for i in used:
            if i in rows:
                xs.append(tk)
                ys.append(rows[i])
    ax.scatter(xs, ys, s=2, marker="s", c="#2a9d3f")
    ax.set_yticks(range(len(landmark_ids)), [str(i) for i in landmark_ids])
    ax.set_ylabel("landmark")
    ax.set_xlabel("time (s)")
    count = np.array([len(u) for u in track.landmarks])
    ax2 = ax.twinx()
    ax2.plot(t, count, color="0.4", lw=0.7)
    ax2.set_ylabel("landmarks used")
    ax2.set_ylim(0, max(int(count.max(initial=0)) + 1, 2))
    ax.set_title("landmarks used per frame")
    return fig


def timing_figure(cpu_s: FloatArray, modes: Sequence[str]) -> Figure:
    """Per-frame processing time (the localizer thread's CPU time), by mode."""
    fig = Figure(figsize=(10.5, 3.0))
    ax = fig.subplots()
    ms = cpu_s * 1000
    m = np.array(modes)
    top = float(np.percentile(ms, 99.5)) if len(ms) else 1.0
    bins = [float(b) for b in np.linspace(0, max(top, 1e-3), 60)]
    for mode, colour in MODE_COLOURS.items():
        sel = m == mode
        if sel.any():
            ax.hist(
                np.clip(ms[sel], 0, bins[-1]),
                bins=bins,
                color=colour,
                alpha=0.7,
                label=f"{mode}: median {np.median(ms[sel]):.2f} ms",
            )
    ax.set_xlabel("per-frame processing time (ms, CPU time of the localizer thread)")
    ax.set_ylabel("frames")
    ax.set_yscale("log")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    return fig
