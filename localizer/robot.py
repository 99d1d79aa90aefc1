"""The robot's wheel geometry (`robot.yaml` of the recording format)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class RobotGeometry:
    """Differential-drive geometry.

    Attributes:
        wheel_base: distance between the wheels, metres (W in eq. 6).
        max_speed: the fastest the robot drives, m/s; sizes the tracking search windows.
    """

    wheel_base: float
    max_speed: float = 1.0

    def __post_init__(self) -> None:
        for name in ("wheel_base", "max_speed"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, int | float)
                or not math.isfinite(v)
                or v <= 0
            ):
                raise ValueError(f"robot: {name} must be a positive number of metres, got {v!r}")


def robot_from_yaml_dict(data: Mapping[str, Any], *, source: str = "robot.yaml") -> RobotGeometry:
    """Build the geometry from parsed `robot.yaml`; ValueError names `source` and the field."""
    if not isinstance(data, Mapping):
        raise ValueError(f"{source}: expected a mapping at the top level")
    if "wheel_base" not in data:
        raise ValueError(f"{source}: missing field 'wheel_base'")
    try:
        return RobotGeometry(wheel_base=data["wheel_base"], max_speed=data.get("max_speed", 1.0))
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None
