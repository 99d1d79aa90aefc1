"""The simulated robots' upward cameras: a nominal wide-angle 640x480 camera for each lens
model, and the "true" camera that differs from it by a realistic calibration error.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel, T_body_camera_upward

Lens = Literal["pinhole", "fisheye"]
LENSES: tuple[Lens, ...] = ("pinhole", "fisheye")
FloatArray = npt.NDArray[np.float64]


def wide_angle_camera(
    lens: Lens,
    *,
    T_body_camera: FloatArray | None = None,
    width: int = 640,
    height: int = 480,
    rate_hz: float = 30.0,
) -> CameraModel:
    """A nominal wide-angle upward camera.

    `pinhole`: OpenCV radial-tangential, f = 0.5 * width (90 deg horizontal field of view
    before distortion) with mild barrel distortion. `fisheye`: OpenCV equidistant,
    f = 0.47 * width (about 120 deg horizontally).

    Args:
        lens: "pinhole" or "fisheye".
        T_body_camera: mounting, shape (4, 4); defaults to `T_body_camera_upward()`.
    """
    T = T_body_camera_upward() if T_body_camera is None else T_body_camera
    cu, cv = (width - 1) / 2.0, (height - 1) / 2.0
    if lens == "pinhole":
        f = 0.5 * width
        return CameraModel(
            width, height, f, f, cu, cv, "radial-tangential",
            np.array([-0.22, 0.05, 0.0, 0.0, 0.0]), T, rate_hz,
        )  # fmt: skip
    if lens == "fisheye":
        f = 0.47 * width
        return CameraModel(
            width, height, f, f, cu, cv, "equidistant",
            np.array([0.02, -0.01, 0.002, 0.0]), T, rate_hz,
        )  # fmt: skip
    raise ValueError(f"lens must be one of {LENSES}, got {lens!r}")


def perturbed_camera(
    nominal: CameraModel,
    rng: np.random.Generator,
    *,
    focal_rel_sigma: float = 0.001,
    principal_sigma_px: float = 0.3,
    distortion_sigma: float = 0.0005,
    mount_angle_sigma_rad: float = 0.001,
    mount_offset_sigma_m: float = 0.001,
) -> CameraModel:
    """The true camera behind a calibrated nominal one: the calibration's residual errors.

    Args:
        nominal: the camera as calibrated (written to `sensor.yaml`).
        rng: draws the errors.
        focal_rel_sigma: relative error of fu and fv.
        principal_sigma_px: error of cu and cv, pixels.
        distortion_sigma: error of the first two distortion coefficients.
        mount_angle_sigma_rad: error of the mounting rotation about each axis, radians.
        mount_offset_sigma_m: error of the mounting offset, metres.
    """
    d = nominal.distortion.copy()
    d[:2] += rng.normal(0.0, distortion_sigma, 2)
    ax, ay, az = rng.normal(0.0, mount_angle_sigma_rad, 3)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    T = nominal.T_body_camera.copy()
    T[:3, :3] = Rz @ Ry @ Rx @ T[:3, :3]
    T[:3, 3] += rng.normal(0.0, mount_offset_sigma_m, 3)
    return dataclasses.replace(
        nominal,
        fu=nominal.fu * (1.0 + rng.normal(0.0, focal_rel_sigma)),
        fv=nominal.fv * (1.0 + rng.normal(0.0, focal_rel_sigma)),
        cu=nominal.cu + rng.normal(0.0, principal_sigma_px),
        cv=nominal.cv + rng.normal(0.0, principal_sigma_px),
        distortion=d,
        T_body_camera=T,
    )
