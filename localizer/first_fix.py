"""The first fix after identification (Sec. III-B with the sightings of Sec. III-A).

Identified landmarks were each seen in their own frame, while the robot moved; each sighting
is carried to the current frame through the odometry in between (`transfer_pixel`), then the
pose is solved from all of them (`solve_pose`), leaving one out when that is what makes the
residual small (a sighting spoiled by a stray source).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import invert_transform, rotation_2d, transform_points, wrap_angle
from localizer.handoff import ceiling_points_body
from localizer.identification import Sighting
from localizer.landmark_map import LandmarkMap
from localizer.pose import PoseFix, solve_pose
from localizer.types import FloatArray

OdometryPose = tuple[float, float, float]


def body_motion(odo_then: OdometryPose, odo_now: OdometryPose) -> tuple[FloatArray, float]:
    """The body's motion from the odometry pose `odo_then` to `odo_now` (x, y, theta; any
    common frame), in the body frame then: (translation (2,), rotation), metres and radians."""
    d_world = np.array([odo_now[0] - odo_then[0], odo_now[1] - odo_then[1]])
    d_body: FloatArray = rotation_2d(-odo_then[2]) @ d_world
    return d_body, float(wrap_angle(odo_now[2] - odo_then[2]))


def transfer_pixel(
    camera: CameraModel,
    pixel: tuple[float, float],
    height_m: float,
    odo_then: OdometryPose,
    odo_now: OdometryPose,
) -> tuple[float, float]:
    """Where a ceiling spot seen at `pixel` appears after the body moved from the odometry
    pose `odo_then` to `odo_now` (x, y, theta; any common frame), pixels."""
    q = ceiling_points_body(camera, np.array([pixel]), np.array([height_m]))[0]
    d_body, dth = body_motion(odo_then, odo_now)
    q_now = rotation_2d(-dth) @ (q - d_body)
    p_body = np.array([[q_now[0], q_now[1], height_m]])
    p_cam = transform_points(invert_transform(camera.T_body_camera), p_body)
    px, _ = pixels_from_points_camera(camera, p_cam)
    return float(px[0, 0]), float(px[0, 1])


def consistent_fix(
    camera: CameraModel,
    pixels: FloatArray,
    positions: FloatArray,
    ids: tuple[int, ...],
    *,
    pixel_sigma_px: float,
    max_residual_px: float,
) -> PoseFix | None:
    """A fix from all landmarks whose reprojection RMS is at most `max_residual_px`, or
    from all but one (with 3 or more), or None.

    Args:
        pixels: the landmarks' spots, shape (N, 2); positions: shape (N, 3).
    """
    subsets = [list(range(len(ids)))]
    if len(ids) >= 3:
        subsets += [[j for j in range(len(ids)) if j != i] for i in range(len(ids))]
    for keep in subsets:
        fix = solve_pose(
            camera,
            pixels[keep],
            positions[keep],
            pixel_sigma_px=pixel_sigma_px,
            landmark_ids=tuple(ids[j] for j in keep),
        )
        if fix is not None and fix.residual_rms_px <= max_residual_px:
            return fix
    return None


def first_fix(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    sightings: Sequence[Sighting],
    odometry_at: Callable[[int], OdometryPose],
    t_ns: int,
    *,
    pixel_sigma_px: float,
    max_residual_px: float,
) -> PoseFix | None:
    """The pose at `t_ns` from identified landmarks, each carried there by odometry.

    Args:
        odometry_at: the raw odometry pose at a time (ns): now, and a sighting's when it
            does not carry its own (`Sighting.odometry`, kept however old it is).
    """
    rows = np.array([landmark_map.index_of(s.landmark_id) for s in sightings])
    P = landmark_map.positions[rows]
    now = odometry_at(t_ns)
    pixels = np.array(
        [
            transfer_pixel(camera, s.pixel, P[i, 2], s.odometry or odometry_at(s.t_ns), now)
            for i, s in enumerate(sightings)
        ]
    )
    ids = tuple(s.landmark_id for s in sightings)
    return consistent_fix(
        camera, pixels, P, ids, pixel_sigma_px=pixel_sigma_px, max_residual_px=max_residual_px
    )
