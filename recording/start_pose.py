"""Where the robot starts: `start_pose.yaml` of a recording, or `irloc replay --start-pose`.

A robot knows where it was parked (ROS users send `/initialpose`, SICK's
`LocInitializeAtPose` takes a pose and a search radius). A recording may carry that prior as
`start_pose.yaml` (optional; docs/recording.md):

    x: 1.20            # metres, world frame
    y: 0.35
    theta: 1.5708      # radians, REP-103 (CCW from +x)
    radius_m: 0.3      # optional: 95 % of the prior within it (default: the localizer's)
    timestamp_ns: 0    # optional: when it holds (default: the recording's first event)

The replay hands it to the localizer as `RelocalizeRequested(near=..., radius_m=...)`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml

from recording import layout

_KEYS = ("x", "y", "theta", "radius_m", "timestamp_ns")


@dataclass(frozen=True)
class StartPose:
    """A prior on the robot's pose at the start of a recording.

    Attributes:
        x, y: metres; theta: radians (REP-103).
        radius_m: the search radius (95 % of the prior inside it), metres; None: the
            localizer's default (`FusionConfig.initial_sigma_m`).
        t_ns: when it holds; None: the recording's first event.
    """

    x: float
    y: float
    theta: float
    radius_m: float | None = None
    t_ns: int | None = None

    def __post_init__(self) -> None:
        for name in ("x", "y", "theta"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        r = self.radius_m
        if r is not None and (isinstance(r, bool) or not math.isfinite(r) or r <= 0):
            raise ValueError(f"radius_m must be a positive number of metres, got {r!r}")
        if self.t_ns is not None and (isinstance(self.t_ns, bool) or self.t_ns < 0):
            raise ValueError(f"timestamp_ns must be a non-negative integer, got {self.t_ns!r}")

    def as_dict(self) -> dict[str, float | int]:
        """The YAML file's keys (unset ones left out)."""
        out: dict[str, float | int] = {"x": self.x, "y": self.y, "theta": self.theta}
        if self.radius_m is not None:
            out["radius_m"] = self.radius_m
        if self.t_ns is not None:
            out["timestamp_ns"] = self.t_ns
        return out


def parse_start_pose(text: str) -> StartPose:
    """`X,Y,THETA[,RADIUS]` (metres, radians, metres) as on the command line.

    Raises:
        ValueError: naming what is wrong with `text`.
    """
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (3, 4):
        raise ValueError(f"expected X,Y,THETA[,RADIUS], got {text!r}")
    values: list[float] = []
    for name, part in zip(("X", "Y", "THETA", "RADIUS"), parts, strict=False):
        try:
            values.append(float(part))
        except ValueError:
            raise ValueError(f"{name} must be a number, got {part!r} in {text!r}") from None
    radius = values[3] if len(values) == 4 else None
    return StartPose(values[0], values[1], values[2], radius)


def start_pose_from_dict(data: object) -> StartPose:
    """The contents of `start_pose.yaml`.

    Raises:
        ValueError: not a mapping, an unknown or missing key, or a bad value (named).
    """
    if not isinstance(data, Mapping):
        raise ValueError(f"expected a mapping with x, y, theta, got {data!r}")
    unknown = sorted(str(k) for k in data if k not in _KEYS)
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r} (known: {', '.join(_KEYS)})")
    missing = [k for k in ("x", "y", "theta") if k not in data]
    if missing:
        raise ValueError(f"missing key {missing[0]!r}")
    t = data.get("timestamp_ns")
    if t is not None and (not isinstance(t, int) or isinstance(t, bool)):
        raise ValueError(f"timestamp_ns must be an integer, got {t!r}")
    radius = data.get("radius_m")
    if radius is not None and (not isinstance(radius, int | float) or isinstance(radius, bool)):
        raise ValueError(f"radius_m must be a number, got {radius!r}")
    return StartPose(data["x"], data["y"], data["theta"], radius, t)


def write_start_pose(root: Path | str, pose: StartPose) -> Path:
    """Write `start_pose.yaml` into a recording folder; returns its path."""
    path = Path(root) / layout.START_POSE_FILE
    path.write_text(yaml.safe_dump(pose.as_dict(), sort_keys=False), encoding="utf-8")
    return path
