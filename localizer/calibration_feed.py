"""The online self-calibration fed from tracking.

Each frame that fused a fix hands its spots, landmarks, pose, raw odometry pose and floor to
`OnlineCalibration` (which takes them in windows and works a completed window off a step a
frame), after the frame's pose is out (`after_frame`). When it hands back a corrected
camera, the pose moves to where this frame's spots put it through the corrected lens: the
filter's belief stays, read through the better lens.
"""

from __future__ import annotations

import numpy as np

from localizer.camera import CameraModel
from localizer.fix_fusion import FixPairs
from localizer.geometry import wrap_angle
from localizer.landmark_map import LandmarkMap
from localizer.noise_model import PixelNoiseModel
from localizer.online_calibration import OnlineCalibration
from localizer.pose import solve_pose
from localizer.pose_filter import PoseFilter


def feed_self_calibration(
    calibration: OnlineCalibration,
    t_ns: int,
    fused: FixPairs,
    noise: PixelNoiseModel,
    filt: PoseFilter,
    landmark_map: LandmarkMap,
    odometry: tuple[float, float, float],
) -> CameraModel | None:
    """Feed the fused fix of the frame at `t_ns` (`LandmarkTracker.last_fused`; `odometry`:
    the raw odometry pose at the frame) to the online self-calibration; when it hands back
    a corrected camera, shift `filt` to where the frame's spots put the pose through it and
    return that camera (None: the camera stays)."""
    rows, px, fix = fused
    completed = calibration.wants(t_ns, len(rows)) and calibration.observe(
        t_ns,
        px,
        landmark_map.positions[rows],
        (fix.x, fix.y, fix.theta),
        odometry,
        fix.floor,
    )
    if not completed:  # a completed window's work goes on a step a frame, not all at once
        calibration.step()
    update = calibration.take_update()
    if update is None:
        return None
    P = landmark_map.positions[rows]
    pose = (fix.x, fix.y, fix.theta)
    sigma = [noise.sigma_px(u, v) for u, v in px]
    # on the floor the fix stood on (its tilt and height), not the map's level one
    on = None
    if fix.floor is not None:
        on = ((float(fix.floor[0]), float(fix.floor[1]), float(fix.floor[2])), np.eye(3) * 1e-12)
    moved = solve_pose(update.camera, px, P, initial=pose, pixel_sigma_px=sigma, floor_prior=on)
    if moved is not None:
        filt.shift(moved.x - fix.x, moved.y - fix.y, float(wrap_angle(moved.theta - fix.theta)))
    return update.camera
