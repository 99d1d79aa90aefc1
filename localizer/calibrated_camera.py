"""The camera the online self-calibration corrects, and its projection with Jacobians.

The six corrections c (`self_calibration.NAMES` order: principal point cu, cv in pixels;
the radial distortion k1, k2 and the focal length, relative; the mounting yaw, radians)
applied to a camera (`corrected_camera`), and landmarks projected from body poses through
the corrected camera with their derivatives by c and by each pose
(`project_with_jacobians`), for the self-calibration's Gauss-Newton adjustment.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel
from localizer.types import FloatArray, IntArray


def corrected_camera(camera: CameraModel, c: npt.ArrayLike) -> CameraModel:
    """`camera` with the corrections c (`NAMES` order) applied."""
    dcu, dcv, dk1, dk2, df, yaw = (float(v) for v in np.asarray(c, dtype=np.float64))
    d = camera.distortion.copy()
    d[0] *= 1.0 + dk1
    d[1] *= 1.0 + dk2
    T = camera.T_body_camera.copy()
    T[:3, :3] = _rz(yaw) @ T[:3, :3]
    return dataclasses.replace(
        camera,
        fu=camera.fu * (1.0 + df),
        fv=camera.fv * (1.0 + df),
        cu=camera.cu + dcu,
        cv=camera.cv + dcv,
        distortion=d,
        T_body_camera=T,
    )


def _rz(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def project_with_jacobians(
    camera: CameraModel,
    c: FloatArray,
    poses: FloatArray,
    P: FloatArray,
    frame: IntArray,
    floors: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pixels of landmarks P seen from body poses through the corrected camera, and their
    derivatives.

    The body stands on the floor its fix found (`floor_plane`): tilted by (roll, pitch) and
    raised by dz, p_body = R_t^T (Rz(theta)^T (P - t) - (0, 0, dz)), R_t = Ry(pitch)
    Rx(roll); level (zeros) without `floors`. The floor is the fix's, held fixed here: it
    is a property of the place, the calibration's corrections of the camera, so a tilt
    the floor explains is not taken for a shift of the principal point.

    Args:
        camera: the handed-over camera; c: corrections (6,).
        poses: body poses (M, 3); P: landmarks (N, 3); frame: each landmark's frame (N,).
        floors: each frame's (roll, pitch, dz), shape (M, 3), or None (level).

    Returns:
        (pixels (N, 2), d pixel / d c (N, 2, 6), d pixel / d own pose (N, 2, 3)).
    """
    dcu, dcv, dk1, dk2, df, yaw = c.tolist()
    fu, fv = camera.fu * (1.0 + df), camera.fv * (1.0 + df)
    K = np.array([[fu, 0.0, camera.cu + dcu], [0.0, fv, camera.cv + dcv], [0.0, 0.0, 1.0]])
    dist = camera.distortion.copy()
    dist[0] *= 1.0 + dk1
    dist[1] *= 1.0 + dk2
    R_bc = _rz(yaw) @ camera.T_body_camera[:3, :3]
    t_bc = camera.T_body_camera[:3, 3]
    x, y, th = poses[frame, 0], poses[frame, 1], poses[frame, 2]
    ct, st = np.cos(th), np.sin(th)
    dx, dy = P[:, 0] - x, P[:, 1] - y
    p_level = np.column_stack([ct * dx + st * dy, -st * dx + ct * dy, P[:, 2]])
    Rt = None
    if floors is not None and np.any(floors):
        f = floors[frame]
        cr, sr, cp, sp = np.cos(f[:, 0]), np.sin(f[:, 0]), np.cos(f[:, 1]), np.sin(f[:, 1])
        Rt = np.zeros((len(P), 3, 3))  # Ry(pitch) Rx(roll) per landmark
        Rt[:, 0, 0], Rt[:, 0, 1], Rt[:, 0, 2] = cp, sp * sr, sp * cr
        Rt[:, 1, 1], Rt[:, 1, 2] = cr, -sr
        Rt[:, 2, 0], Rt[:, 2, 1], Rt[:, 2, 2] = -sp, cp * sr, cp * cr
        p_level = p_level - np.column_stack([np.zeros(len(P)), np.zeros(len(P)), f[:, 2]])
        p_level = np.einsum("nji,nj->ni", Rt, p_level)  # R_t^T p
    p_body = p_level - t_bc
    p_cam = p_body @ R_bc  # R_bc^T p_body, row-wise
    z3 = np.zeros(3)
    obj = np.ascontiguousarray(p_cam.reshape(-1, 1, 3))
    if camera.distortion_model == "equidistant":
        px, J = cv2.fisheye.projectPoints(obj, z3, z3, K, dist)
        jf, jc, jk, jp = J[:, 0:2], J[:, 2:4], J[:, 4:6], J[:, 11:14]
    else:
        px, J = cv2.projectPoints(obj, z3, z3, K, dist)
        jp, jf, jc, jk = J[:, 3:6], J[:, 6:8], J[:, 8:10], J[:, 10:12]
    n = len(P)
    jp = jp.reshape(n, 2, 3)  # d pixel / d p_cam
    d_c = np.zeros((n, 2, 6))
    d_c[:, :, 0:2] = jc.reshape(n, 2, 2)
    jk = jk.reshape(n, 2, 2)
    d_c[:, :, 2] = jk[:, :, 0] * camera.distortion[0]
    d_c[:, :, 3] = jk[:, :, 1] * camera.distortion[1]
    jf = jf.reshape(n, 2, 2)
    d_c[:, :, 4] = jf[:, :, 0] * camera.fu + jf[:, :, 1] * camera.fv
    # yaw: p_cam = (Rz(yaw) R0)^T p_body, d/dyaw = R0^T Rz'(yaw)^T p_body
    dRz = np.array(
        [
            [-math.sin(yaw), -math.cos(yaw), 0.0],
            [math.cos(yaw), -math.sin(yaw), 0.0],
            [0.0, 0.0, 0.0],
        ]
    )
    dp_yaw = p_body @ (dRz @ camera.T_body_camera[:3, :3])
    d_c[:, :, 5] = np.einsum("nij,nj->ni", jp, dp_yaw)
    # pose: p_body = Rz(-th) (P - t) - t_bc
    d_body = np.zeros((n, 3, 3))  # d p_body / d (x, y, th)
    d_body[:, 0, 0], d_body[:, 0, 1] = -ct, -st
    d_body[:, 1, 0], d_body[:, 1, 1] = st, -ct
    d_body[:, 0, 2] = -st * dx + ct * dy
    d_body[:, 1, 2] = -ct * dx - st * dy
    if Rt is not None:  # the tilt turns the level frame's derivatives: R_t^T d
        d_body = np.einsum("nji,njk->nik", Rt, d_body)
    d_pose = np.einsum("nij,jk,nkl->nil", jp, R_bc.T, d_body)
    return np.asarray(px, dtype=np.float64).reshape(n, 2), d_c, d_pose
