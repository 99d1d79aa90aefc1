"""What the localizer outputs for a frame: the pose estimate with its published covariance,
quality and deviation radius (`PoseEstimate`), or `NoPose` before the first fix, each with
the reason a frame had no fix (`pose_quality.reason_for`) from the facts the localizer knew
of it (`FrameFacts`: the ceiling in view, the LEDs, the odometry, the camera's timing).
"""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.events import Mode, NoPose, PoseEstimate
from localizer.geometry import wrap_angle
from localizer.handoff import visible_radius_m
from localizer.landmark_map import LandmarkMap
from localizer.led_knowledge import LedKnowledge
from localizer.pose_filter import PoseFilter
from localizer.pose_quality import (
    FrameFacts,
    QualityConfig,
    deviation_radius_m,
    is_landmark_fix,
    landmarks_in_view,
    published_covariance,
    quality_from_deviation,
    reason_for,
    reason_text,
)
from localizer.recovery import Recovery

_NS = 1e-9


class FrameTiming:
    """The camera's timing: the interval between the last two frames and the usual one.

    Attributes:
        t_last_ns: the last frame's time (None: none yet).
        interval_s: between the last two frames (at most 1 s; None: fewer than two).
        typical_gap_s: the usual frame interval, smoothed, seconds (0: not known yet).
    """

    def __init__(self) -> None:
        self.t_last_ns: int | None = None
        self.interval_s: float | None = None
        self.typical_gap_s = 0.0

    def frame(self, t: int) -> tuple[float, dict[str, bool | int | float]]:
        """A frame at `t`: the interval from the frame before (at most 1 s; 0 for the
        first), and the frame's first notes (its gap and the usual one before it)."""
        dt_frame = min((t - self.t_last_ns) * _NS, 1.0) if self.t_last_ns is not None else 0.0
        if dt_frame > 0:
            self.interval_s = dt_frame
        notes: dict[str, bool | int | float] = {
            "gap_s": dt_frame,
            "typical_gap_s": self.typical_gap_s,
        }
        if 0 < dt_frame < 1.0:
            g = self.typical_gap_s
            self.typical_gap_s = dt_frame if g == 0 else min(g + 0.1 * (dt_frame - g), dt_frame)
        self.t_last_ns = t
        return dt_frame, notes


def frame_output(
    t_ns: int,
    filt: PoseFilter | None,
    pose: tuple[float, float, float] | None,
    mode: Mode,
    used: tuple[int, ...],
    expected: tuple[int, ...],
    facts: FrameFacts | None,
    config: QualityConfig,
) -> PoseEstimate | NoPose:
    """The frame's output: `NoPose` without a filter, else the filter's output pose (`pose`,
    `PoseFilter.output_pose`) with the covariance published for `mode`
    (`published_covariance`) and its quality; the reason from `facts` when the frame had
    no fix (None: it had a landmark fix, no reason to give)."""
    code = None if facts is None else reason_for(facts)
    text = "" if code is None or facts is None else reason_text(code, facts)
    if filt is None or pose is None:
        return NoPose(t_ns, mode, reason=code, reason_text=text)
    x, y, theta = pose
    sx, sy, sth = filt.pose
    offset = (x - sx, y - sy, float(wrap_angle(theta - sth)))
    cov = published_covariance(filt.covariance, mode, offset, config)
    deviation = deviation_radius_m(cov)
    return PoseEstimate(
        t_ns=t_ns,
        x=x,
        y=y,
        theta=theta,
        covariance=cov,
        mode=mode,
        landmark_ids=used,
        expected_ids=expected,
        quality=quality_from_deviation(deviation, config),
        deviation_m=deviation,
        reason=code,
        reason_text=text,
    )


def frame_facts(
    t_ns: int,
    pose: tuple[float, float, float] | None,
    used: tuple[int, ...],
    *,
    mode: Mode,
    notes: dict[str, bool | int | float],
    recovery: Recovery,
    leds: LedKnowledge,
    camera: CameraModel,
    landmark_map: LandmarkMap,
    t_odometry_ns: int | None,
    config: LocalizerConfig,
) -> FrameFacts | None:
    """What explains this frame's lack of a fix (`pose_quality.reason_for`; None for a
    landmark fix, `is_landmark_fix`: nothing to explain); the ceiling in view is worked out
    only for a pose without a fix.

    Args:
        pose: the output pose (None: none yet).
        used: the landmarks whose spots the frame's fix used.
        notes: what the frame noted on its way (gap_s, typical_gap_s, unexplained,
            rejected_fix, skipped).
        t_odometry_ns: the last odometry sample's time (None: none yet).
    """
    if is_landmark_fix(mode, bool(used)):
        return None
    f = notes
    age = math.inf if t_odometry_ns is None else (t_ns - t_odometry_ns) * _NS
    ic = config.identification
    awaiting = leds.awaiting(t_ns, ic.led_timeout_s)
    in_view = lit = switching = 0
    dark: tuple[int, ...] = ()
    dead: tuple[int, ...] = ()
    if pose is not None and not used and mode in ("landmark", "dead_reckoning"):
        heights = landmark_map.positions[:, 2] - float(camera.T_body_camera[2, 3])
        reach = visible_radius_m(camera, float(np.max(heights, initial=0.0)))
        rows = np.flatnonzero(landmarks_in_view(camera, pose, landmark_map.positions, reach))
        ids = [int(landmark_map.ids[r]) for r in rows]
        in_view = len(ids)
        switching = sum(1 for i in ids if i in leds.changing)
        dark = tuple(
            i for i in ids if leds.lit is not None and i not in leds.lit and i not in leds.changing
        )
        lit_rows = [
            r for r, i in zip(rows, ids, strict=True) if i not in leds.changing and i not in dark
        ]
        lit = len(lit_rows)
        live = recovery.liveness
        dead = tuple(
            int(landmark_map.ids[r]) for r in lit_rows if not live.lit[r] and live.unseen[r] >= 3
        )
    return FrameFacts(
        mode=mode,
        fused=bool(used),
        lost_by_disagreement=recovery.lost_by_disagreement,
        in_view=in_view,
        lit_in_view=lit,
        switching_in_view=switching,
        dark_ids=dark,
        dead_ids=dead,
        unexplained=bool(f.get("unexplained", False)),
        rejected_fix=bool(f.get("rejected_fix", False)),
        rejections=recovery.rejections,
        gap_s=float(f.get("gap_s", 0.0)),
        typical_gap_s=float(f.get("typical_gap_s", 0.0)),
        skipped=bool(f.get("skipped", False)),
        odometry_age_s=age,
        odometry_stale_s=config.fusion.odometry_stale_s,
        awaiting_leds=awaiting,
    )
