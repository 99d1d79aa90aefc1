"""Test cameras shared by the estimation tests: a 640x480 wide-angle camera (~300 px focal
length) with either lens model, and a few mountings."""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel, T_body_camera_upward

# lens name -> (distortion model, coefficients); realistic wide-angle values, monotonic over
# the whole image
LENSES = {
    "pinhole": ("radial-tangential", [0.0, 0.0, 0.0, 0.0]),
    "radial-tangential": ("radial-tangential", [-0.25, 0.05, 2e-4, -3e-4, 0.0]),
    "equidistant": ("equidistant", [-0.013, 0.021, -0.019, 0.0068]),
}
MOUNTINGS = {
    "upward": T_body_camera_upward(),
    "offset-yaw90": T_body_camera_upward(yaw=math.pi / 2, offset_xy=(0.1, 0.0), height=0.35),
    "offset-tilted": T_body_camera_upward(yaw=-2.0, offset_xy=(-0.05, 0.1), tilt_xy=(0.01, -0.015)),
}


def make_camera(
    lens: str = "radial-tangential", mounting: str | np.ndarray = "upward"
) -> CameraModel:
    """The test camera with a named lens and a named (or given (4, 4)) mounting."""
    model, dist = LENSES[lens]
    return CameraModel(
        width=640,
        height=480,
        fu=300.0,
        fv=300.5,
        cu=321.3,
        cv=238.7,
        distortion_model=model,  # type: ignore[arg-type]
        distortion=np.array(dist),
        T_body_camera=MOUNTINGS[mounting] if isinstance(mounting, str) else mounting,
    )
