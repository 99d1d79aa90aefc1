"""What the live survey shows: its state, and each landmark's proposal (docs/survey.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from live.survey.live import LandmarkSurveyState
from survey.result import LandmarkEstimate

State = Literal["idle", "driving", "solving", "done", "failed", "interrupted"]


@dataclass(frozen=True)
class Proposal:
    """One landmark's surveyed position (metres, world frame) against the map's.

    `ellipse`: the horizontal 1-sigma ellipse (major m, minor m, angle of the major axis rad);
    `state`: anchor, converging, converged or flagged (`live.survey.live.landmark_state`).
    """

    landmark_id: int
    x: float
    y: float
    z: float
    sigma_m: float
    moved_m: float
    views: int
    rms_px: float
    anchor: bool
    flags: tuple[str, ...]
    ellipse: tuple[float, float, float] = (0.0, 0.0, 0.0)
    state: LandmarkSurveyState = "converging"


@dataclass(frozen=True)
class SurveyStatus:
    """Where the survey is.

    Attributes:
        state: idle, driving (recording, blinking, estimating), solving, done (the final
            proposals), failed (`message` says why) or interrupted (the server restarted
            during the drive: the running estimate is kept and shown; `start` goes on from
            it, `cancel` drops it).
        robot: the surveying robot; recording: its recording folder.
        started_s: seconds since the drive started (None when idle).
        blinks: dark windows requested so far.
        proposals: the estimate, landmark by landmark: the live one while driving (and
            solving), the final one when done.
        accepted: landmarks whose proposal was written into the map.
        unseen: landmarks of the map the estimate could not place (yet).
        drive_s: robot time the estimate covers, seconds (0 before the first estimate).
        estimates: live estimates made so far.
        route: suggested waypoints ((x, y) metres) over what is still uncertain.
        converged_sigma_m: the 1-sigma at or under which a landmark counts as converged.
        no_radio: landmarks of the map left out of the survey because the radio cannot
            switch them (no radio address): they cannot blink, so nothing names them, and
            counted as dark they would make every blink ambiguous.
    """

    state: State
    robot: str | None = None
    recording: str | None = None
    started_s: float | None = None
    blinks: int = 0
    message: str = ""
    proposals: tuple[Proposal, ...] = ()
    accepted: tuple[int, ...] = ()
    unseen: tuple[int, ...] = field(default=())
    drive_s: float = 0.0
    estimates: int = 0
    route: tuple[tuple[float, float], ...] = ()
    converged_sigma_m: float = 0.005
    no_radio: tuple[int, ...] = ()


def no_radio_text(ids: tuple[int, ...]) -> str:
    """The status line's note on the landmarks a survey leaves out."""
    return (
        f"not surveyed (no radio, cannot blink): {', '.join(map(str, ids))}; give them their "
        "radio address to survey them"
    )


def proposal(e: LandmarkEstimate, state: LandmarkSurveyState) -> Proposal:
    moved = 0.0 if e.given is None else math.dist(e.position.tolist(), e.given.tolist())
    x, y, z = (float(v) for v in e.position)
    return Proposal(
        e.id,
        x,
        y,
        z,
        0.0 if e.anchor else e.sigma_m,
        moved,
        e.views,
        e.rms_px if math.isfinite(e.rms_px) else 0.0,
        e.anchor,
        e.flags,
        (0.0, 0.0, 0.0) if e.anchor else e.ellipse(),
        state,
    )
