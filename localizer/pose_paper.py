"""The paper's closed form (Sec. III-B, eqs. 1-3), kept as the baseline.

`pose_from_landmark_pair` works in the image plane with one scale s = D/d and needs
undistorted pixels, landmarks at one height and the camera on the axle;
`pixels_from_pose_paper` is its inverse, the paper's eq. (3) with the bracket put where it
belongs; `heading_from_paper_angle` turns the paper's theta into a REP-103 heading. The
production solver is `pose.solve_pose`.

Frames: see docs/conventions.md and docs/estimation.md.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from localizer.geometry import wrap_angle
from localizer.types import FloatArray


def pose_from_landmark_pair(
    px_i: npt.ArrayLike,
    px_j: npt.ArrayLike,
    P_i: npt.ArrayLike,
    P_j: npt.ArrayLike,
    image_center: npt.ArrayLike,
) -> tuple[float, float, float]:
    """Robot position and heading from two landmarks, the paper's eqs. (1)-(2).

    cos(theta) = (dx dX + dy dY) / (d D),  sin(theta) = (dx dY - dy dX) / (d D),   (1)
    (r_x, r_y) = s R(theta) ((c_x, c_y) - (x_i, y_i)) + (X_i, Y_i),  s = D / d,     (2)

    with (dx, dy) = p_j - p_i in the image, (dX, dY) = P_j - P_i in the world, d and D their
    lengths. theta is the rotation that turns image directions into world directions.

    Frame mapping (derived in docs/estimation.md). With OpenCV pixels (col, row) of an upward
    camera, the map from the image to the floor is a proper similarity (no mirror): the camera
    frame (x right, y down, z up) is right-handed with z along world z, so (col, row) turn into
    world (x, y) by a rotation. Only an image *displayed* with rows down and read as a map with
    y up looks mirrored. For the mounting `T_body_camera_upward(yaw=gamma)` the image's
    "up" direction (-row) is the robot's forward axis rotated by gamma, and the paper's theta
    relates to our REP-103 heading by heading = theta - gamma - pi/2 (see
    `heading_from_paper_angle`). (r_x, r_y) is the floor point under the optical centre: the
    robot's position only when the camera sits on the axle.

    Exact only for undistorted pixels of an ideal pinhole, both landmarks at one height, the
    optical axis vertical and `image_center` the principal point (cu, cv).

    Args:
        px_i, px_j: pixels (col, row) of landmarks i and j, shape (2,).
        P_i, P_j: their world positions, shape (2,) or (3,) (z is ignored), metres.
        image_center: (c_x, c_y), pixels.

    Returns:
        (r_x, r_y) metres and the paper's theta, radians in (-pi, pi].

    Raises:
        ValueError: when the two landmarks coincide in the image or in the world.
    """
    p_i, p_j = np.asarray(px_i, float)[:2], np.asarray(px_j, float)[:2]
    W_i, W_j = np.asarray(P_i, float)[:2], np.asarray(P_j, float)[:2]
    dx, dy = p_j - p_i
    dX, dY = W_j - W_i
    d, D = math.hypot(dx, dy), math.hypot(dX, dY)
    if d == 0.0 or D == 0.0:
        raise ValueError(f"pose_from_landmark_pair: landmarks coincide (d={d} px, D={D} m)")
    cos_t = (dx * dX + dy * dY) / (d * D)
    sin_t = (dx * dY - dy * dX) / (d * D)
    s = D / d
    R = np.array([[cos_t, -sin_t], [sin_t, cos_t]])
    r = s * R @ (np.asarray(image_center, float)[:2] - p_i) + W_i
    return float(r[0]), float(r[1]), float(wrap_angle(math.atan2(sin_t, cos_t)))


def heading_from_paper_angle(theta_paper: float, camera_yaw: float = 0.0) -> float:
    """REP-103 heading from the paper's theta, for `T_body_camera_upward(yaw=camera_yaw)`.

    heading = theta_paper - camera_yaw - pi/2, wrapped to (-pi, pi].
    """
    return float(wrap_angle(theta_paper - camera_yaw - 0.5 * math.pi))


def pixels_from_pose_paper(
    r_xy: npt.ArrayLike,
    theta_paper: float,
    scale: float,
    image_center: npt.ArrayLike,
    P_world: npt.ArrayLike,
) -> FloatArray:
    """Predicted pixels of landmarks, the paper's eq. (3) with its bracket corrected.

    (x_k', y_k') = (c_x, c_y) - (1/s) R(theta)^T ((r_x, r_y) - (X_k, Y_k)),

    the inverse of eq. (2). (The printed eq. (3) closes the bracket after (r_x, r_y), which
    subtracts a world position from a pixel.)

    Args:
        r_xy: (r_x, r_y), metres; theta_paper: radians; scale: s of eq. (2), metres/pixel.
        image_center: (c_x, c_y), pixels.
        P_world: landmark positions, shape (N, 2) or (N, 3) (z ignored).

    Returns:
        shape (N, 2), pixels.
    """
    c, s = math.cos(theta_paper), math.sin(theta_paper)
    Rt = np.array([[c, s], [-s, c]])
    P = np.asarray(P_world, dtype=np.float64)
    diff = np.asarray(r_xy, dtype=np.float64)[:2] - P.reshape(P.shape[0], -1)[:, :2]
    out: FloatArray = np.asarray(image_center, dtype=np.float64)[:2] - (diff @ Rt.T) / scale
    return out
