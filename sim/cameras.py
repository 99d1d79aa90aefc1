"""The simulated robots' upward cameras: a nominal wide-angle 640x480 camera for each lens
model, and the "true" camera that differs from it by a calibration error: a good
calibration's residual (`perturbed_camera`), or one of the levels of `CALIBRATION_LEVELS`
(`miscalibrated_camera`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np

from localizer.camera import CameraModel, DistortionModel, T_body_camera_upward
from localizer.types import FloatArray

Lens = Literal["pinhole", "fisheye", "wide_radtan"]
LENSES: tuple[Lens, ...] = ("pinhole", "fisheye", "wide_radtan")


# lens: (focal length over image width, OpenCV model, distortion coefficients)
_LENS_TABLE: dict[str, tuple[float, DistortionModel, list[float]]] = {
    "pinhole":     (0.5,     "radial-tangential", [-0.22, 0.05, 0.0, 0.0, 0.0]),
    "fisheye":     (0.47,    "equidistant",       [0.02, -0.01, 0.002, 0.0]),
    "wide_radtan": (0.46875, "radial-tangential", [-0.28, 0.07, 4e-4, -3e-4, -0.006]),
}  # fmt: skip


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
    f = 0.47 * width (about 120 deg horizontally). `wide_radtan`: a strong wide-angle lens as
    Zhang's method calibrates it (OpenCV radial-tangential, f = 0.46875 * width, i.e. 300 px at
    640x480, k1 = -0.28, k2 = 0.07, small decentring p1, p2 and k3; about 118 deg across the
    diagonal).

    Args:
        lens: one of `LENSES`.
        T_body_camera: mounting, shape (4, 4); defaults to `T_body_camera_upward()`.
    """
    T = T_body_camera_upward() if T_body_camera is None else T_body_camera
    cu, cv = (width - 1) / 2.0, (height - 1) / 2.0
    if lens not in _LENS_TABLE:
        raise ValueError(f"lens must be one of {LENSES}, got {lens!r}")
    f_per_width, model, distortion = _LENS_TABLE[lens]
    f = f_per_width * width
    return CameraModel(width, height, f, f, cu, cv, model, np.array(distortion), T, rate_hz)


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
    angles = rng.normal(0.0, mount_angle_sigma_rad, 3)
    T = _moved_mount(nominal.T_body_camera, angles, rng.normal(0.0, mount_offset_sigma_m, 3))
    return dataclasses.replace(
        nominal,
        fu=nominal.fu * (1.0 + rng.normal(0.0, focal_rel_sigma)),
        fv=nominal.fv * (1.0 + rng.normal(0.0, focal_rel_sigma)),
        cu=nominal.cu + rng.normal(0.0, principal_sigma_px),
        cv=nominal.cv + rng.normal(0.0, principal_sigma_px),
        distortion=d,
        T_body_camera=T,
    )


@dataclass(frozen=True)
class CalibrationError:
    """How far the calibration handed to the localizer (the nominal camera, `sensor.yaml`) is
    from the true lens: the bound of each parameter's error.

    Each error is drawn per seed with a random sign and a magnitude uniform in
    [0.5, 1] x its bound, so every seed carries an error of about the stated size.

    Attributes:
        focal_rel: relative error of fu and fv (each drawn on its own).
        principal_px: error of cu and cv, pixels.
        distortion_rel: relative error of each distortion coefficient.
        mount_rad: error of the mounting rotation about each axis, radians.
        mount_m: error of the mounting offset along each axis, metres.
    """

    focal_rel: float = 0.0
    principal_px: float = 0.0
    distortion_rel: float = 0.0
    mount_rad: float = 0.0
    mount_m: float = 0.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not 0.0 <= v <= (50.0 if f.name == "principal_px" else 1.0):
                raise ValueError(f"calibration error: {f.name} out of range, got {v!r}")


CALIBRATION_LEVELS: dict[str, CalibrationError] = {
    "none": CalibrationError(),
    "realistic": CalibrationError(focal_rel=0.002, principal_px=0.6, distortion_rel=0.05),
    "poor": CalibrationError(focal_rel=0.006, principal_px=1.8, distortion_rel=0.15),
}
"""The named levels: `realistic` is what Zhang's method leaves on a wide lens (focal 0.2 %,
principal point 0.6 px, each distortion coefficient 5 %); `poor` about three times that."""


def _signed(rng: np.random.Generator, bound: float, n: int) -> FloatArray:
    """`n` errors of random sign and magnitude uniform in [0.5, 1] x `bound`."""
    sign = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    return sign * rng.uniform(0.5, 1.0, n) * bound


def miscalibrated_camera(
    nominal: CameraModel, error: CalibrationError, rng: np.random.Generator
) -> CameraModel:
    """The true camera behind a nominal one handed over with calibration `error`.

    Args:
        nominal: the camera as calibrated (written to `sensor.yaml`).
        error: the bound of each parameter's error.
        rng: draws the errors (the same number of draws whatever the bounds).
    """
    df, dc, dd = (
        _signed(rng, error.focal_rel, 2),
        _signed(rng, error.principal_px, 2),
        _signed(rng, error.distortion_rel, len(nominal.distortion)),
    )
    angles, offset = _signed(rng, error.mount_rad, 3), _signed(rng, error.mount_m, 3)
    return dataclasses.replace(
        nominal,
        fu=nominal.fu * (1.0 + df[0]),
        fv=nominal.fv * (1.0 + df[1]),
        cu=nominal.cu + dc[0],
        cv=nominal.cv + dc[1],
        distortion=nominal.distortion * (1.0 + dd),
        T_body_camera=_moved_mount(nominal.T_body_camera, angles, offset),
    )


def _moved_mount(T_body_camera: FloatArray, angles: FloatArray, offset: FloatArray) -> FloatArray:
    """The mounting (4, 4) turned by small `angles` about body x, y, z and moved by `offset`."""
    ax, ay, az = (float(a) for a in angles)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    T = T_body_camera.copy()
    T[:3, :3] = Rz @ Ry @ Rx @ T[:3, :3]
    T[:3, 3] += offset
    return T
