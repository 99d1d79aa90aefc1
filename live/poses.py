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
    quality: float | None = None
    deviation_m: float | None = None
    reason: ReasonCode | None = None
    reason_text: str = ""

    @classmethod
    def from_estimate(cls, robot: str, est: PoseEstimate) -> PoseUpdate:
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
            quality=est.quality,
            deviation_m=est.deviation_m,
            reason=est.reason,
            reason_text=est.reason_text,
        )

    @classmethod
    def from_no_pose(cls, robot: str, out: NoPose) -> PoseUpdate:
        return cls(robot, out.t_ns, out.mode, quality=out.quality, reason=out.reason,
                   reason_text=out.reason_text)  # fmt: skip

    def estimate(self) -> PoseEstimate | None:
        """This update as the localizer's estimate; None when it carries no pose."""
        if self.x is None or self.y is None or self.theta is None:
            return None
        cov = np.zeros((3, 3)) if self.covariance is None else self.covariance
        return PoseEstimate(
            self.t_ns, self.x, self.y, self.theta, cov, self.mode, self.landmark_ids,
            self.expected_ids, quality=self.quality, deviation_m=self.deviation_m,
            reason=self.reason, reason_text=self.reason_text,
        )  # fmt: skip

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
            "quality": self.quality,
            "deviation_m": self.deviation_m,
            "reason": self.reason,
            "reason_text": self.reason_text,
        }

    @cached_property
    def json(self) -> str:
        """The JSON text sent on the WebSocket (encoded once, shared by every client)."""
        return json.dumps(self.to_dict(), separators=(",", ":"))


def pose_json(robot: str, mode: Mode, upd: PoseUpdate | None) -> str:
    """`PosePublic` as JSON text, built without a model round trip (the hot endpoint)."""
    if upd is None:
        return json.dumps(
            {
                "robot": robot,
                "mode": mode,
                "t_ns": None,
                "x": None,
                "y": None,
                "theta": None,
                "covariance": None,
                "landmark_ids": [],
                "age_s": None,
                "quality": 0.0,
                "deviation_m": None,
                "reason": None,
                "reason_text": "",
            }
        )
    d = upd.to_dict()
    d.pop("computed_wall_ns")
    d["mode"] = mode
    d["age_s"] = max(0.0, (time.time_ns() - upd.computed_wall_ns) / 1e9)
    return json.dumps(d, separators=(",", ":"))


class PosePublic(BaseModel):
    """`GET /robots/{name}/pose`: the latest result of a robot's localizer."""

    robot: str
    mode: Mode
    t_ns: int | None = None
    x: float | None = None
    y: float | None = None
    theta: float | None = None
    covariance: list[list[float]] | None = None
    landmark_ids: list[int] = []
    age_s: float | None = None
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
