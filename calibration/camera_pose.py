"""The camera's full pose in the world from landmarks of known position (PnP).

Unlike `localizer.pose.solve_pose`, which finds the *body* pose through a known mounting,
this finds the camera's own 6-DoF pose, so it serves to measure an unknown mounting. The
pixels are undistorted with the lens model first (`normalized_from_pixels`), so both lens
models work, then `cv2.solvePnP` runs on the normalised points (K = identity): SQPnP for
four or more landmarks (any layout, coplanar or not), P3P for three (keeping the solution
whose optical axis is nearest the vertical: the camera looks up), then Levenberg-Marquardt.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, normalized_from_pixels, pixels_from_points_camera
from localizer.geometry import invert_transform, transform_points
from localizer.types import FloatArray


@dataclass(frozen=True, eq=False)
class CameraPose:
    """A camera pose measured from landmarks.

    Attributes:
        T_world_camera: camera-to-world transform, shape (4, 4).
        residual_rms_px: RMS reprojection error of the landmarks, pixels.
        count: landmarks used.
    """

    T_world_camera: FloatArray
    residual_rms_px: float
    count: int


def camera_pose_from_landmarks(
    camera: CameraModel,
    pixels: npt.ArrayLike,
    p_world: npt.ArrayLike,
    *,
    near_world_m: npt.ArrayLike | None = None,
) -> CameraPose | None:
    """Solve the camera pose from three or more landmarks seen at `pixels`.

    Args:
        camera: lens model and intrinsics (the mounting is not used).
        pixels: where the landmarks appear, shape (N, 2), N >= 3.
        p_world: the landmarks' world positions, metres, shape (N, 3).
        near_world_m: where the camera was a moment ago (world, metres, shape (3,)): with
            three landmarks P3P has up to four solutions, and the one nearest this is taken
            (without it, the one looking most upward).

    Returns:
        The pose, or None when there are fewer than three landmarks or no solution.
    """
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    pw = np.asarray(p_world, dtype=np.float64).reshape(-1, 3)
    if len(px) != len(pw):
        raise ValueError(f"camera pose: {len(px)} pixels but {len(pw)} landmark positions")
    if len(px) < 3:
        return None
    xy = normalized_from_pixels(camera, px)
    obj = np.ascontiguousarray(pw)
    img = np.ascontiguousarray(xy)
    K, dist = np.eye(3), np.zeros(4)
    try:
        if len(px) == 3:
            n, rvecs, tvecs = cv2.solveP3P(obj, img, K, dist, flags=cv2.SOLVEPNP_P3P)
            if n == 0:
                return None
            # the camera looks up: its optical axis in the world (R^T row 3) has the largest z
            ups = [cv2.Rodrigues(r)[0][2, 2] for r in rvecs]
            best = int(np.argmax(ups))
            if near_world_m is not None:
                near = np.asarray(near_world_m, dtype=np.float64).reshape(3)
                gaps = [
                    float(np.linalg.norm(-cv2.Rodrigues(r)[0].T @ np.reshape(t, 3) - near))
                    for r, t in zip(rvecs, tvecs, strict=True)
                ]
                best = int(np.argmin(gaps))
            rvec, tvec = rvecs[best], tvecs[best]
        else:
            ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_SQPNP)
            if not ok:
                return None
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    except cv2.error:
        return None
    T_camera_world = np.eye(4)
    T_camera_world[:3, :3] = cv2.Rodrigues(rvec)[0]
    T_camera_world[:3, 3] = np.asarray(tvec, dtype=np.float64).reshape(3)
    pred, valid = pixels_from_points_camera(camera, transform_points(T_camera_world, pw))
    if not np.all(valid):
        return None
    rms = float(np.sqrt(np.mean(np.sum((pred - px) ** 2, axis=1))))
    return CameraPose(invert_transform(T_camera_world), rms, len(px))
