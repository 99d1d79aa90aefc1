"""One measurement of the identification wizard: a frame with one lit LED and the robot's
estimate for that frame turned into a proposed landmark position."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from web.geometry import landmark_from_spot
from web.services import CameraView, LandmarkState, ViewerSite


@dataclass(frozen=True, eq=False)
class Measurement:
    """What one lighting of a landmark gave.

    Attributes:
        landmark_id: the landmark lit alone.
        view: the frame used, with its detected spots (None when no frame came).
        spot: the chosen spot's pixel (col, row), None when no spot was seen.
        position: the computed LED position in the world frame, shape (3,), or None.
        robot_pose: (x, y, theta) used, or None when the robot was not localized.
        message: what happened, for the staff.
    """

    landmark_id: int
    view: CameraView | None
    spot: npt.NDArray[np.float64] | None
    position: npt.NDArray[np.float64] | None
    robot_pose: tuple[float, float, float] | None
    message: str


def measure_landmark(
    site: ViewerSite,
    robot: str,
    landmark_id: int,
    landmark: LandmarkState | None,
    view: CameraView | None,
    pose: tuple[float, float, float] | None,
    why_no_pose: str,
) -> Measurement:
    """Turn a frame with one lit LED into a proposed landmark position."""
    if view is None:
        return Measurement(landmark_id, None, None, None, pose, f"no new frame from {robot}")
    if len(view.spots) == 0:
        return Measurement(
            landmark_id, view, None, None, pose,
            f"no spot seen: is landmark {landmark_id} in {robot}'s view? Move it, or retry",
        )  # fmt: skip
    spot = np.asarray(view.spots[0], dtype=np.float64)
    extra = f" ({len(view.spots)} spots; the brightest is used)" if len(view.spots) > 1 else ""
    if pose is None:
        return Measurement(landmark_id, view, spot, None, None, why_no_pose + extra)
    height = landmark.z if landmark is not None else None
    if height is None or not math.isfinite(height):
        height = site.ceiling_height()
    cam = next(r.camera for r in site.robots() if r.name == robot)
    p = landmark_from_spot(cam, *pose, spot, height)
    if p is None:
        return Measurement(landmark_id, view, spot, None, pose, "the spot's ray misses the ceiling")
    return Measurement(landmark_id, view, spot, p, pose, describe(landmark_id, p, landmark, extra))


def describe(
    landmark_id: int, p: npt.NDArray[np.float64], landmark: LandmarkState | None, extra: str
) -> str:
    """The measured position for people, with its distance from the map's."""
    text = f"landmark {landmark_id} at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m{extra}"
    if landmark is not None:
        d = math.hypot(p[0] - landmark.x, p[1] - landmark.y)
        text += f", {100 * d:.1f} cm from the map"
    return text
