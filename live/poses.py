"""What the pose bus carries and what the API returns for a robot's pose."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, Field

from localizer.events import Mode, NoPose, PoseEstimate
from localizer.pose_quality import ReasonCode
from store.models import DEFAULT_FLOOR


@dataclass(frozen=True, eq=False)
class PoseUpdate:
    """One robot's localizer result for one frame, as published on the pose bus.

    Attributes:
        robot: the robot's name.
        t_ns: the frame's time on the site clock, nanoseconds.
        mode: the localizer's mode.
        x, y, theta: metres, metres, radians (REP-103); None while there is no pose.
        covariance: of (x, y, theta), shape (3, 3), or None.
        landmark_ids: landmarks used in this frame.
        expected_ids: the lit landmarks the localizer expected in view at this frame
            (`PoseEstimate.expected_ids`; read by doubt detection, not sent by the API).
        computed_wall_ns: wall clock (`time.time_ns`) when the pose was computed, for ages
            and latency measurements.
        floor: the floor whose map the pose is on (its frame: that floor's map frame).
        map_version: the version of that floor's map the localizer held.
        floor_unknown: the robot's view does not fit its floor's map (it changed floors
            untold, or rides a lift): its pose is withheld (x, y, theta None) until it is
            told its floor or fits its map again (`fleet.floor_fit`).
        quality: 0-1 (docs/quality.md); None: not known (a pose from an older agent).
        deviation_m: the radius holding the true position with 95 % probability, metres.
        reason: why this is no landmark fix (a `pose_quality.ReasonCode`), None when it is.
        reason_text: the same for people.
    """

    robot: str
    t_ns: int
    mode: Mode
    x: float | None = None
    y: float | None = None
    theta: float | None = None
    covariance: npt.NDArray[np.float64] | None = None
    landmark_ids: tuple[int, ...] = ()
    computed_wall_ns: int = field(default_factory=time.time_ns)
    expected_ids: tuple[int, ...] = ()
    floor: str = DEFAULT_FLOOR
    map_version: int = 0
    floor_unknown: bool = False
    quality: float | None = None
    deviation_m: float | None = None
    reason: ReasonCode | None = None
    reason_text: str = ""

    @classmethod
    def from_estimate(
        cls, robot: str, est: PoseEstimate, *, floor: str = DEFAULT_FLOOR, map_version: int = 0
    ) -> PoseUpdate:
        return cls(
            robot,
            est.t_ns,
            est.mode,
            float(est.x),
            float(est.y),
            float(est.theta),
            np.asarray(est.covariance, dtype=np.float64),
            tuple(est.landmark_ids),
            expected_ids=tuple(est.expected_ids),
            floor=floor,
            map_version=map_version,
            quality=est.quality,
            deviation_m=est.deviation_m,
            reason=est.reason,
            reason_text=est.reason_text,
        )

    @classmethod
    def from_no_pose(
        cls, robot: str, out: NoPose, *, floor: str = DEFAULT_FLOOR, map_version: int = 0
    ) -> PoseUpdate:
        return cls(
            robot,
            out.t_ns,
            out.mode,
            quality=out.quality,
            reason=out.reason,
            reason_text=out.reason_text,
            floor=floor,
            map_version=map_version,
        )

    def estimate(self) -> PoseEstimate | None:
        """This update as the localizer's estimate; None when it carries no pose."""
        if self.x is None or self.y is None or self.theta is None:
            return None
        cov = np.zeros((3, 3)) if self.covariance is None else self.covariance
        return PoseEstimate(
            self.t_ns,
            self.x,
            self.y,
            self.theta,
            cov,
            self.mode,
            self.landmark_ids,
            self.expected_ids,
            quality=self.quality,
            deviation_m=self.deviation_m,
            reason=self.reason,
            reason_text=self.reason_text,
        )

    def to_dict(self) -> dict[str, Any]:
        cov = None if self.covariance is None else self.covariance.tolist()
        return {
            "robot": self.robot,
            "t_ns": self.t_ns,
            "mode": self.mode,
            "x": self.x,
            "y": self.y,
            "theta": self.theta,
            "covariance": cov,
            "landmark_ids": list(self.landmark_ids),
            "computed_wall_ns": self.computed_wall_ns,
            "floor": self.floor,
            "map_version": self.map_version,
            "floor_unknown": self.floor_unknown,
            "quality": self.quality,
            "deviation_m": self.deviation_m,
            "reason": self.reason,
            "reason_text": self.reason_text,
        }

    @cached_property
    def json(self) -> str:
        """The JSON text sent on the WebSocket (encoded once, shared by every client)."""
        return json.dumps(self.to_dict(), separators=(",", ":"))


NO_POSE_MODES: frozenset[str] = frozenset({"identifying", "lost"})
"""Modes in which the robot has no pose to give (as the WebSocket sends none)."""


def pose_json(
    robot: str,
    mode: Mode,
    upd: PoseUpdate | None,
    *,
    floor: str = DEFAULT_FLOOR,
    map_version: int = 0,
    now: PoseUpdate | None = None,
) -> str:
    """`PosePublic` as JSON text, built without a model round trip (the hot endpoint);
    `floor` and `map_version` are the robot's now (used when it has no pose yet), `now` its
    latest update with a pose or without (its quality and reason are the current ones).

    While the robot identifies again (after a relocalize) or is lost, its last pose is not
    served as if current: x, y, theta, covariance are null and `stale` is true (`t_ns` and
    `age_s` still say when the last pose was computed), and the quality and reason are those
    of the latest update (why there is no pose)."""
    stale = mode in NO_POSE_MODES
    if upd is None:
        d: dict[str, Any] = {
            "robot": robot,
            "mode": mode,
            "t_ns": None,
            "x": None,
            "y": None,
            "theta": None,
            "covariance": None,
            "landmark_ids": [],
            "age_s": None,
            "stale": stale,
            "floor": floor,
            "map_version": map_version,
            "quality": 0.0,
            "deviation_m": None,
            "reason": None,
            "reason_text": "",
            "floor_unknown": False,
        }
    else:
        d = upd.to_dict()
        d.pop("computed_wall_ns")
        d["mode"] = mode
        d["age_s"] = max(0.0, (time.time_ns() - upd.computed_wall_ns) / 1e9)
        d["stale"] = stale = stale or upd.floor_unknown
        if stale:
            d.update(x=None, y=None, theta=None, covariance=None, landmark_ids=[])
            d.update(quality=0.0, deviation_m=None)
    if (stale or upd is None) and now is not None:
        d.update(
            quality=now.quality if now.quality is not None else 0.0,
            reason=now.reason,
            reason_text=now.reason_text,
        )
    return json.dumps(d, separators=(",", ":"))


class PosePublic(BaseModel):
    """`GET /robots/{name}/pose`: the latest result of a robot's localizer."""

    robot: str
    mode: Mode
    t_ns: int | None = Field(
        default=None,
        description="when the frame of this pose was taken, on the site clock (nanoseconds "
        "since the site's clock epoch: the server's start for the virtual site, the robot "
        "agent's synchronised clock otherwise); not wall time",
    )
    x: float | None = Field(default=None, description="metres, world (map) frame")
    y: float | None = Field(default=None, description="metres, world (map) frame")
    theta: float | None = Field(
        default=None, description="heading, radians, REP-103: CCW from +x, in (-pi, pi]"
    )
    covariance: list[list[float]] | None = Field(
        default=None, description="of (x, y, theta): m^2, m*rad, rad^2; 3x3 row-major"
    )
    landmark_ids: list[int] = Field(default=[], description="landmarks this fix used")
    age_s: float | None = Field(
        default=None, description="seconds since the pose was computed (wall clock)"
    )
    stale: bool = Field(
        default=False,
        description="true while the robot identifies again or is lost: x, y, theta and "
        "covariance are then null (its last pose is no longer current)",
    )
    floor: str = Field(DEFAULT_FLOOR, description="the floor whose map the pose is on")
    map_version: int = Field(0, description="the version of that floor's map it is on")
    floor_unknown: bool = Field(
        default=False,
        description="true while the robot's view does not fit its floor's map (it changed "
        "floors untold, or rides a lift): x, y, theta and covariance are then null and "
        "stale is true until it is told its floor or fits its map again",
    )
    quality: float | None = Field(
        default=None, description="0-1 from deviation_m (docs/quality.md); null: not known"
    )
    deviation_m: float | None = Field(
        default=None, description="radius holding the true position with 95 % probability, m"
    )
    reason: ReasonCode | None = Field(
        default=None, description="why this is no landmark fix (docs/quality.md); null: it is"
    )
    reason_text: str = ""
