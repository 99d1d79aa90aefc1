"""`sensor_msgs/CameraInfo` against the calibrated camera: the lens a camera driver
announces must be the one irloc localizes with.

With a `sensor.yaml` (EuRoC: intrinsics, distortion and the camera's mounting on the
robot) the camera_info is checked against it and frames are refused while they disagree
(`camera_info_disagreement`); without one the lens is taken from the camera_info and the
mounting from the settings (`camera_from_camera_info`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from localizer.camera import CameraModel
from localizer.types import FloatArray

ROS_TO_MODEL = {
    "plumb_bob": "radial-tangential",
    "rational_polynomial": "radial-tangential",
    "equidistant": "equidistant",
}
FOCAL_TOLERANCE = 0.005
"""Relative focal-length difference above which camera_info and sensor.yaml disagree (0.5 %;
a recalibration moves it by 0.2 %)."""
CENTRE_TOLERANCE_PX = 2.0
DISTORTION_TOLERANCE = 0.01


def _lens(info: Any) -> tuple[int, int, float, float, float, float, str, list[float]]:
    k = [float(v) for v in info.k]
    if len(k) != 9:
        raise ValueError(f"camera_info k must hold 9 numbers, got {len(k)}")
    return (
        int(info.width),
        int(info.height),
        k[0],
        k[4],
        k[2],
        k[5],
        str(info.distortion_model),
        [float(v) for v in info.d],
    )


def camera_info_disagreement(info: Any, camera: CameraModel) -> list[str]:
    """What `info` (a CameraInfo) says differently from the calibrated `camera`, one
    sentence a field; empty when they agree within the tolerances above."""
    w, h, fu, fv, cu, cv, model, d = _lens(info)
    out: list[str] = []
    if (w, h) != (camera.width, camera.height):
        out.append(f"size {w}x{h} vs {camera.width}x{camera.height}")
    for name, got, want in (("fx", fu, camera.fu), ("fy", fv, camera.fv)):
        if abs(got - want) > FOCAL_TOLERANCE * want:
            out.append(f"{name} {got:.2f} vs {want:.2f} px")
    for name, got, want in (("cx", cu, camera.cu), ("cy", cv, camera.cv)):
        if abs(got - want) > CENTRE_TOLERANCE_PX:
            out.append(f"{name} {got:.2f} vs {want:.2f} px")
    mapped = ROS_TO_MODEL.get(model)
    if mapped != camera.distortion_model:
        out.append(f"distortion_model {model!r} vs {camera.distortion_model}")
    else:
        ours = list(camera.coefficients)
        theirs = (d + [0.0] * len(ours))[: len(ours)]
        if any(abs(a - b) > DISTORTION_TOLERANCE for a, b in zip(theirs, ours, strict=True)) or any(
            abs(v) > DISTORTION_TOLERANCE for v in d[len(ours) :]
        ):
            out.append(f"d {[round(v, 4) for v in d]} vs {[round(v, 4) for v in ours]}")
    return out


def camera_from_camera_info(
    info: Any, T_body_camera: FloatArray, rate_hz: float = 30.0
) -> CameraModel:
    """The camera a CameraInfo describes, mounted at `T_body_camera` (shape (4, 4)).

    Raises:
        ValueError: an unknown distortion model, an uncalibrated camera (K all zeros) or
            coefficients the model does not take.
    """
    w, h, fu, fv, cu, cv, model, d = _lens(info)
    mapped = ROS_TO_MODEL.get(model)
    if mapped is None:
        raise ValueError(
            f"camera_info distortion_model {model!r} is not one of {sorted(ROS_TO_MODEL)}"
        )
    if fu <= 0 or fv <= 0:
        raise ValueError("camera_info k is zero: the camera is not calibrated")
    n = 4 if mapped == "equidistant" else 5
    coeffs = (d + [0.0] * n)[:n]
    if any(abs(v) > 0 for v in d[n:]):
        raise ValueError(f"camera_info d has {len(d)} coefficients; {model} is used with {n}")
    return CameraModel(
        width=w,
        height=h,
        fu=fu,
        fv=fv,
        cu=cu,
        cv=cv,
        distortion_model=mapped,  # type: ignore[arg-type]
        distortion=np.asarray(coeffs, dtype=np.float64),
        T_body_camera=T_body_camera,
        rate_hz=rate_hz,
    )


def camera_info_of(camera: CameraModel, t_ns: int, frame_id: str) -> Any:
    """The CameraInfo a driver of `camera` publishes (K, P = [K | 0], R = I)."""
    from ros2.messages import header, new

    K = [camera.fu, 0.0, camera.cu, 0.0, camera.fv, camera.cv, 0.0, 0.0, 1.0]
    model = "equidistant" if camera.distortion_model == "equidistant" else "plumb_bob"
    return new(
        "sensor_msgs/msg/CameraInfo",
        header=header(t_ns, frame_id),
        height=camera.height,
        width=camera.width,
        distortion_model=model,
        d=[float(v) for v in camera.coefficients],
        k=K,
        r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p=[K[0], 0.0, K[2], 0.0, 0.0, K[4], K[5], 0.0, 0.0, 0.0, 1.0, 0.0],
    )
