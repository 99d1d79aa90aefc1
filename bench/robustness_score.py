"""Scoring of one robustness-matrix run against the simulator's truth (see
`bench/robustness.py` and `docs/robustness.md`).

Only the localizer's outputs are scored (poses, modes, the landmark IDs each frame used), so
the scorer works whatever the localizer does inside:

- position error (p95, max) and heading error (mean, max) over every frame with a pose that
  the localizer stands by (any mode but `lost` and `identifying`), except while the robot is
  carried by a kidnapper (it is in the air);
- frames in each mode;
- **wrong-ID frames**: a frame whose output names a landmark that is not the one truly at
  that spot. Each named landmark is projected from the surveyed map through the nominal
  camera at the estimated planar pose, with the body's true tilt and lift (where the fit put
  that landmark's spot); the true IR source
  nearest to that pixel (every lit-able landmark and glint, through the true camera at the
  true pose) must be that landmark;
- **gross frames**: a `landmark`-mode pose more than `GROSS_POSITION_M` or
  `GROSS_HEADING_RAD` off (a confident wrong fix); **misidentified** = wrong-ID or gross.
  Dead-reckoning poses that far off are counted on their own (`dr_off`);
- time to recover after each kidnap: from the moment the robot is put down to the first
  `landmark`-mode frame within `RECOVERED_M` / `RECOVERED_RAD` of the truth after which it
  stays within them (every posed frame) for `RECOVERED_HOLD_S`.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from localizer.camera import CameraModel, T_camera_world, predict_pixels
from localizer.geometry import T_world_body_from_pose, transform_points, wrap_angle
from localizer.types import BoolArray, FloatArray, IntArray

GROSS_POSITION_M = 0.25
GROSS_HEADING_RAD = math.radians(5.0)
RECOVERED_M = 0.10
RECOVERED_RAD = math.radians(3.0)
RECOVERED_HOLD_S = 1.0
EDGE_MARGIN_PX = 25.0
"""A landmark projected this far outside the image still counts as seen (a spot at the very
edge, projected through a slightly different camera or pose, may land just outside)."""
UNSCORED_MODES = ("lost", "identifying")
"""Poses the localizer itself does not stand by: counted as frames of their mode only."""


@dataclass(frozen=True)
class FrameResult:
    """One frame's output: the pose (None: no pose), its mode, the landmark IDs it used."""

    t_ns: int
    pose: tuple[float, float, float] | None
    mode: str
    landmark_ids: tuple[int, ...] = ()


@dataclass(frozen=True, eq=False)
class SiteTruth:
    """What the simulator really used, and what the localizer was told.

    Attributes:
        sources: every lit-able landmark and glint, true positions (S, 3).
        source_ids: the landmark ID of each source, -1 for a glint, shape (S,).
        camera_true, camera_nominal: the rendering camera and the calibration handed over.
        surveyed: landmark ID -> surveyed position (3,) (map.json).
        T_world_body: the true body pose (4, 4) on the floor at a planar pose.
    """

    sources: FloatArray
    source_ids: IntArray
    camera_true: CameraModel
    camera_nominal: CameraModel
    surveyed: dict[int, FloatArray]
    T_world_body: Callable[[float, float, float], FloatArray]


@dataclass
class Score:
    """The figures of one run (lengths in metres, angles in radians, times in seconds)."""

    frames: int
    posed: int
    p95_m: float
    max_m: float
    heading_mean_rad: float
    heading_max_rad: float
    modes: dict[str, int]
    wrong_id: int
    gross: int
    misidentified: int
    dr_off: int
    first_pose_s: float | None
    recover_s: list[float | None] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def share(self, mode: str) -> float:
        return self.modes.get(mode, 0) / self.frames if self.frames else 0.0


def wrong_ids(
    truth: SiteTruth,
    pose_est: tuple[float, float, float],
    pose_true: tuple[float, float, float],
    landmark_ids: Sequence[int],
) -> list[str]:
    """The named landmarks of one frame that are not the one truly at their spot (a short
    description of each; empty when all are right)."""
    ids = [i for i in landmark_ids if i in truth.surveyed]
    unknown = [f"{i} is not on the map" for i in landmark_ids if i not in truth.surveyed]
    if not ids:
        return unknown
    p_map = np.array([truth.surveyed[i] for i in ids])
    # The localizer outputs a planar pose; the body's tilt and lift (a floor bump, a tilted
    # floor) are the floor's. The claimed pixels take them from the truth, so a body tilted
    # by a bump (5 deg moves a spot ~20 px) does not put a landmark the localizer named
    # correctly onto a glint beside it.
    T_true = truth.T_world_body(*pose_true)
    T_tilt = np.linalg.inv(T_world_body_from_pose(*pose_true)) @ T_true
    claimed, ok = _pixels(truth.camera_nominal, T_world_body_from_pose(*pose_est) @ T_tilt, p_map)
    seen, valid = _pixels(truth.camera_true, T_true, truth.sources)
    seen[~valid] = np.inf
    out = unknown
    for lid, (u, v), inside in zip(ids, claimed, ok, strict=True):
        if not inside:
            out.append(f"{lid} would be outside the image at the estimated pose")
            continue
        d = np.hypot(seen[:, 0] - u, seen[:, 1] - v)
        j = int(np.argmin(d))
        if int(truth.source_ids[j]) != lid:
            what = "a glint" if truth.source_ids[j] < 0 else f"landmark {truth.source_ids[j]}"
            out.append(f"{lid} at ({u:.0f}, {v:.0f}) is {what} ({d[j]:.0f} px)")
    return out


def _pixels(
    cam: CameraModel, T_world_body: FloatArray, p: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """Pixels of world points (N, 2) and whether each is in the field of view and within
    `EDGE_MARGIN_PX` of the image."""
    px, _ = predict_pixels(cam, T_world_body, p)
    pc = transform_points(T_camera_world(cam, T_world_body), p)
    z, norm = pc[:, 2], np.linalg.norm(pc, axis=1)
    m = EDGE_MARGIN_PX
    ok = (z > 1e-9) & (z >= math.cos(cam.max_angle_rad) * norm)
    ok &= (px[:, 0] >= -m) & (px[:, 0] <= cam.width - 1 + m)
    ok &= (px[:, 1] >= -m) & (px[:, 1] <= cam.height - 1 + m)
    return px, ok


def score(
    results: Sequence[FrameResult],
    truth_poses: Callable[[int], tuple[float, float, float]],
    site: SiteTruth | None,
    *,
    kidnaps: Sequence[tuple[int, int]] = (),
    t_start_ns: int = 0,
) -> Score:
    """Score a run's outputs against the truth.

    Args:
        results: the outputs, one per frame, in time order.
        truth_poses: the true planar pose at a frame's time.
        site: the site's truth for the wrong-ID check (None: not checked).
        kidnaps: (picked up, put down) times; frames in between are not scored.
        t_start_ns: the start of the run (for the time to the first pose).
    """
    modes = Counter(r.mode for r in results)
    err: list[float] = []
    herr: list[float] = []
    wrong = gross = dr_off = misid = 0
    notes: list[str] = []
    per_frame: list[tuple[int, float, float, str] | None] = []
    first: float | None = None
    for r in results:
        if r.pose is None or r.mode in UNSCORED_MODES or any(a <= r.t_ns <= b for a, b in kidnaps):
            per_frame.append(None)
            continue
        if first is None:
            first = (r.t_ns - t_start_ns) * 1e-9
        tx, ty, tth = truth_poses(r.t_ns)
        x, y, th = r.pose
        e, h = math.hypot(x - tx, y - ty), abs(float(wrap_angle(th - tth)))
        err.append(e)
        herr.append(h)
        per_frame.append((r.t_ns, e, h, r.mode))
        far = e > GROSS_POSITION_M or h > GROSS_HEADING_RAD
        bad = wrong_ids(site, r.pose, (tx, ty, tth), r.landmark_ids) if site else []
        wrong += bool(bad)
        is_gross = far and r.mode == "landmark"
        gross += is_gross
        dr_off += far and r.mode != "landmark"
        misid += bool(bad) or is_gross
        if (bad or is_gross) and len(notes) < 5:
            what = "; ".join(bad) if bad else f"{r.mode} pose {100 * e:.0f} cm off"
            notes.append(f"t={(r.t_ns - t_start_ns) * 1e-9:.2f} s: {what}")
    e_arr, h_arr = np.array(err), np.array(herr)
    return Score(
        frames=len(results),
        posed=len(err),
        p95_m=float(np.percentile(e_arr, 95)) if len(e_arr) else math.inf,
        max_m=float(e_arr.max()) if len(e_arr) else math.inf,
        heading_mean_rad=float(h_arr.mean()) if len(h_arr) else math.inf,
        heading_max_rad=float(h_arr.max()) if len(h_arr) else math.inf,
        modes=dict(modes),
        wrong_id=wrong,
        gross=gross,
        misidentified=misid,
        dr_off=dr_off,
        first_pose_s=first,
        recover_s=[_recovery(per_frame, drop) for _, drop in kidnaps],
        notes=notes,
    )


def _recovery(
    per_frame: Sequence[tuple[int, float, float, str] | None], drop_ns: int
) -> float | None:
    """Seconds from `drop_ns` to the first landmark-mode frame within the recovered bounds
    that stays so for `RECOVERED_HOLD_S`; None if never."""
    frames = [f for f in per_frame if f is not None and f[0] >= drop_ns]
    hold_ns = round(RECOVERED_HOLD_S * 1e9)
    for k, (t, e, h, mode) in enumerate(frames):
        if mode != "landmark" or e > RECOVERED_M or h > RECOVERED_RAD:
            continue
        later = [f for f in frames[k:] if f[0] <= t + hold_ns]
        if frames[-1][0] >= t + hold_ns and all(
            f[1] <= RECOVERED_M and f[2] <= RECOVERED_RAD for f in later
        ):
            return (t - drop_ns) * 1e-9
    return None
