"""The upward camera: lens model (OpenCV pinhole + radial-tangential, or equidistant fisheye)
and its mounting on the robot (`T_body_camera`, the EuRoC `T_BS`).

Pixel conventions are OpenCV's: the centre of pixel (col, row) is at (col, row); the camera
frame has x right, y down, z along the optical axis. All lens math goes through OpenCV.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import cv2
import numpy as np
import numpy.typing as npt

from localizer.geometry import check_transform, invert_transform, transform_points
from localizer.types import BoolArray, FloatArray

DistortionModel = Literal["radial-tangential", "equidistant"]
Row4 = tuple[float, float, float, float]
Rows3x4 = tuple[Row4, Row4, Row4]
DISTORTION_MODELS: tuple[DistortionModel, ...] = ("radial-tangential", "equidistant")

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
ROUND_TRIP_TOLERANCE_PX = 0.01
"""An undistorted pixel must reproject to itself within this many pixels, else it is NaN."""
_CHECK_GRID = (33, 25)
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)  # pixels sampled over the image to decide whether every pixel inverts


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Intrinsics, lens distortion and mounting of one camera.

    Attributes:
        width, height: image size in pixels.
        fu, fv, cu, cv: focal lengths and principal point, pixels.
        distortion_model: "radial-tangential" (OpenCV k1 k2 p1 p2 [k3]) or
            "equidistant" (OpenCV fisheye k1 k2 k3 k4).
        distortion: the coefficients, shape (4,) or (5,); `coefficients` holds them as a
            tuple of floats (derived).
        T_body_camera: body-from-camera transform, shape (4, 4) (EuRoC `T_BS`);
            `T_body_camera_rows` and `T_camera_body_rows` hold the top three rows of it and of
            its inverse as tuples of floats (derived, for code on Python floats).
        max_angle_rad: the largest angle from the optical axis in view (derived), and
            `cos_max_angle` its cosine.
        rate_hz: nominal frame rate.
    """

    width: int
    height: int
    fu: float
    fv: float
    cu: float
    cv: float
    distortion_model: DistortionModel
    distortion: FloatArray
    T_body_camera: FloatArray = field(default_factory=lambda: np.eye(4))
    rate_hz: float = 30.0
    max_angle_rad: float = field(init=False, repr=False, compare=False)
    cos_max_angle: float = field(init=False, repr=False, compare=False)
    K_matrix: FloatArray = field(init=False, repr=False, compare=False)
    T_camera_body: FloatArray = field(init=False, repr=False, compare=False)
    invertible: bool = field(init=False, repr=False, compare=False)
    coefficients: tuple[float, ...] = field(init=False, repr=False, compare=False)
    T_body_camera_rows: Rows3x4 = field(init=False, repr=False, compare=False)
    T_camera_body_rows: Rows3x4 = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera: resolution must be positive, got {self.width}x{self.height}")
        for name in ("fu", "fv"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"camera: {name} must be a positive number, got {v!r}")
        for name in ("cu", "cv"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"camera: {name} must be finite")
        if self.distortion_model not in DISTORTION_MODELS:
            raise ValueError(
                f"camera: distortion_model must be one of {DISTORTION_MODELS}, "
                f"got {self.distortion_model!r}"
            )
        d = np.asarray(self.distortion, dtype=np.float64).reshape(-1)
        allowed = (4,) if self.distortion_model == "equidistant" else (4, 5)
        if len(d) not in allowed or not np.all(np.isfinite(d)):
            raise ValueError(
                f"camera: {self.distortion_model} wants {' or '.join(map(str, allowed))} finite "
                f"distortion coefficients, got {d.tolist()}"
            )
        d.setflags(write=False)
        object.__setattr__(self, "distortion", d)
        object.__setattr__(self, "coefficients", tuple(d.tolist()))
        T = check_transform(self.T_body_camera, "camera T_BS").copy()
        T.setflags(write=False)
        object.__setattr__(self, "T_body_camera", T)
        if not math.isfinite(self.rate_hz) or self.rate_hz <= 0:
            raise ValueError(f"camera: rate_hz must be positive, got {self.rate_hz!r}")
        K = np.array([[self.fu, 0.0, self.cu], [0.0, self.fv, self.cv], [0.0, 0.0, 1.0]])
        K.setflags(write=False)
        object.__setattr__(self, "K_matrix", K)
        T_cb = invert_transform(T)
        T_cb.setflags(write=False)
        object.__setattr__(self, "T_camera_body", T_cb)
        object.__setattr__(self, "T_body_camera_rows", _rows3x4(T))
        object.__setattr__(self, "T_camera_body_rows", _rows3x4(T_cb))
        object.__setattr__(self, "invertible", _every_pixel_inverts(self))
        object.__setattr__(self, "max_angle_rad", _field_of_view_half_angle(self))
        object.__setattr__(self, "cos_max_angle", math.cos(self.max_angle_rad))

    @property
    def K(self) -> FloatArray:
        """The 3x3 intrinsic matrix (read-only)."""
        return self.K_matrix

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return (self.width, self.height)


def _rows3x4(T: FloatArray) -> Rows3x4:
    """The top three rows of a (4, 4) transform as tuples of floats."""
    (a, b, c, d), (e, f, g, h), (i, j, k, m) = T[:3].tolist()
    return (a, b, c, d), (e, f, g, h), (i, j, k, m)


def _field_of_view_half_angle(cam: CameraModel) -> float:
    """Largest angle from the optical axis seen anywhere in the image, plus 5 %; for a lens
    whose image reaches past its fold-back, the largest angle of the pixels that invert."""
    if cam.invertible:
        corners = np.array(
            [
                [0, 0],
                [cam.width - 1, 0],
                [0, cam.height - 1],
                [cam.width - 1, cam.height - 1],
                [cam.width / 2, 0],
                [cam.width / 2, cam.height - 1],
                [0, cam.height / 2],
                [cam.width - 1, cam.height / 2],
            ],
            dtype=np.float64,
        )
        rays = rays_from_pixels(cam, corners)
        angle = float(np.max(np.arccos(np.clip(rays[:, 2], -1.0, 1.0))))
        return min(angle * 1.05, math.radians(89.0))
    grid = _check_grid(cam)
    xy = _undistort(cam, grid)[_round_trips(cam, grid, _undistort(cam, grid))]
    if len(xy) == 0:
        raise ValueError("camera: no pixel of the image inverts through the lens model")
    return min(float(np.arctan(np.max(np.hypot(xy[:, 0], xy[:, 1])))), math.radians(89.0))


def _check_grid(cam: CameraModel) -> FloatArray:
    """Pixels over the whole image, shape (N, 1, 2)."""
    cols = np.linspace(-0.5, cam.width - 0.5, _CHECK_GRID[0])
    rows = np.linspace(-0.5, cam.height - 0.5, _CHECK_GRID[1])
    return np.ascontiguousarray(np.stack(np.meshgrid(cols, rows), axis=-1).reshape(-1, 1, 2))


def _every_pixel_inverts(cam: CameraModel) -> bool:
    """Whether every pixel of a grid over the image round-trips through the lens model (true
    for usual lenses; false when the image reaches past a radial-tangential fold-back)."""
    grid = _check_grid(cam)
    return bool(np.all(_round_trips(cam, grid, _undistort(cam, grid))))


def _round_trips(cam: CameraModel, px: FloatArray, xy: FloatArray) -> BoolArray:
    """Which undistorted points (N, 2) reproject to their pixels (N, 1, 2)."""
    with np.errstate(invalid="ignore"):
        err = np.hypot(*(_distort(cam, xy) - px[:, 0, :]).T)
    ok: BoolArray = err <= ROUND_TRIP_TOLERANCE_PX
    return ok


def _undistort(cam: CameraModel, px: FloatArray) -> FloatArray:
    """OpenCV's undistortion of pixels shape (N, 1, 2) to normalised coordinates (N, 2)."""
    if cam.distortion_model == "equidistant":
        out = cv2.fisheye.undistortPoints(
            px, cam.K_matrix, cam.distortion, criteria=_UNDISTORT_CRITERIA
        )
    else:
        out = cv2.undistortPoints(px, cam.K_matrix, cam.distortion, criteria=_UNDISTORT_CRITERIA)
    xy: FloatArray = np.asarray(out, dtype=np.float64).reshape(-1, 2)
    return xy


def _distort(cam: CameraModel, xy: FloatArray) -> FloatArray:
    """OpenCV's projection of normalised coordinates (N, 2) to pixels (N, 2)."""
    obj = np.ones((len(xy), 1, 3))
    obj[:, 0, :2] = xy
    if cam.distortion_model == "equidistant":
        px, _ = cv2.fisheye.projectPoints(obj, _ZERO3, _ZERO3, cam.K_matrix, cam.distortion)
    else:
        px, _ = cv2.projectPoints(obj, _ZERO3, _ZERO3, cam.K_matrix, cam.distortion)
    out: FloatArray = np.asarray(px, dtype=np.float64).reshape(-1, 2)
    return out


def normalized_from_pixels(cam: CameraModel, pixels: npt.ArrayLike) -> FloatArray:
    """Undistorted normalised image coordinates (x/z, y/z) of pixels.

    A pixel the lens model cannot have produced comes back as NaN: past the fold-back radius
    of a radial-tangential model with strong barrel distortion (where the distortion
    polynomial turns negative), OpenCV's iterative undistortion stops and silently returns
    the undistorted pinhole value (u - cu) / fu, (v - cv) / fv, which is wrong, or it does not
    converge. So when the camera's image reaches such pixels (`CameraModel.invertible` is
    False) every result is projected back and kept only if it lands within
    `ROUND_TRIP_TOLERANCE_PX` of its pixel.

    Args:
        pixels: shape (N, 2), (col, row).

    Returns:
        shape (N, 2); NaN rows for pixels without an inverse.
    """
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
    if len(px) == 0:
        return np.zeros((0, 2))
    if not px.flags.c_contiguous:  # (a nested list comes contiguous: skip the copy's call)
        px = np.ascontiguousarray(px)
    xy = _undistort(cam, px)
    if not cam.invertible:
        xy[~_round_trips(cam, px, xy)] = np.nan
    return xy


def rays_from_pixels(cam: CameraModel, pixels: npt.ArrayLike) -> FloatArray:
    """Unit bearing vectors in the camera frame for pixels of shape (N, 2); returns (N, 3)."""
    xy = normalized_from_pixels(cam, pixels)
    rays = np.column_stack([xy, np.ones(len(xy))])
    unit: FloatArray = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    return unit


def bearings_body_from_pixels(cam: CameraModel, pixels: npt.ArrayLike) -> FloatArray:
    """Unit bearing vectors in the body frame for pixels of shape (N, 2); returns (N, 3)."""
    return rays_from_pixels(cam, pixels) @ cam.T_body_camera[:3, :3].T


def pixels_from_points_camera(
    cam: CameraModel, p_camera: npt.ArrayLike
) -> tuple[FloatArray, BoolArray]:
    """Project points in the camera frame to pixels.

    Args:
        p_camera: shape (N, 3), metres.

    Returns:
        (pixels shape (N, 2), valid shape (N,)); a point is valid when it lies in front of the
        camera within the lens's field of view and projects inside the image.
    """
    p = np.asarray(p_camera, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        return np.zeros((0, 2)), np.zeros(0, dtype=bool)
    z = p[:, 2]
    # in the field of view: angle from the axis <= max_angle, i.e. z / |p| >= cos(max_angle)
    in_view = (z > 1e-9) & (z >= cam.cos_max_angle * np.sqrt((p * p).sum(axis=1)))
    safe = p if in_view.all() else np.where(in_view[:, None], p, np.array([0.0, 0.0, 1.0]))
    obj = np.ascontiguousarray(safe.reshape(-1, 1, 3))
    if cam.distortion_model == "equidistant":
        px, _ = cv2.fisheye.projectPoints(obj, _ZERO3, _ZERO3, cam.K_matrix, cam.distortion)
    else:
        px, _ = cv2.projectPoints(obj, _ZERO3, _ZERO3, cam.K_matrix, cam.distortion)
    px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
    u, v = px[:, 0], px[:, 1]
    inside = (u >= -0.5) & (u <= cam.width - 0.5) & (v >= -0.5) & (v <= cam.height - 0.5)
    return px, in_view & inside


def T_camera_world(cam: CameraModel, T_world_body: FloatArray) -> FloatArray:
    """Camera-from-world transform for a body pose, shape (4, 4)."""
    return invert_transform(T_world_body @ cam.T_body_camera)


def predict_pixels(
    cam: CameraModel, T_world_body: FloatArray, p_world: npt.ArrayLike
) -> tuple[FloatArray, BoolArray]:
    """Where world points appear in the image for a body pose (Sec. IV-A.2, eq. 3 in 3D).

    Args:
        T_world_body: body pose, shape (4, 4) (a tilted body is allowed).
        p_world: shape (N, 3).

    Returns:
        (pixels shape (N, 2), valid shape (N,)), as `pixels_from_points_camera`.
    """
    p_camera = transform_points(T_camera_world(cam, T_world_body), np.asarray(p_world))
    return pixels_from_points_camera(cam, p_camera)


def camera_from_sensor(data: Mapping[str, Any], *, source: str = "sensor.yaml") -> CameraModel:
    """Build a camera from the parsed EuRoC `sensor.yaml` mapping.

    Raises:
        ValueError: naming `source` and the missing or malformed field.
    """
    if not isinstance(data, Mapping):
        raise ValueError(f"{source}: expected a mapping at the top level")

    def need(key: str) -> Any:
        if key not in data:
            raise ValueError(f"{source}: missing field '{key}'")
        return data[key]

    def numbers(key: str, count: tuple[int, ...]) -> list[float]:
        v = need(key)
        if not isinstance(v, list | tuple) or len(v) not in count:
            raise ValueError(f"{source}: '{key}' must be a list of {count} numbers, got {v!r}")
        try:
            out = [float(x) for x in v]
        except (TypeError, ValueError):
            raise ValueError(f"{source}: '{key}' must hold numbers, got {v!r}") from None
        return out

    model = need("camera_model")
    if model != "pinhole":
        raise ValueError(f"{source}: camera_model must be 'pinhole', got {model!r}")
    fu, fv, cu, cv_ = numbers("intrinsics", (4,))
    res = numbers("resolution", (2,))
    dist_model = need("distortion_model")
    if dist_model not in DISTORTION_MODELS:
        raise ValueError(
            f"{source}: distortion_model must be one of {DISTORTION_MODELS}, got {dist_model!r}"
        )
    dist = numbers("distortion_coefficients", (4, 5))
    T_BS = data.get("T_BS", {"rows": 4, "cols": 4, "data": np.eye(4).reshape(-1).tolist()})
    if not isinstance(T_BS, Mapping) or "data" not in T_BS:
        raise ValueError(f"{source}: 'T_BS' must be a mapping with rows, cols, data")
    if T_BS.get("rows", 4) != 4 or T_BS.get("cols", 4) != 4 or len(T_BS["data"]) != 16:
        raise ValueError(f"{source}: 'T_BS' must be 4x4 with 16 numbers")
    try:
        T = np.array([float(x) for x in T_BS["data"]]).reshape(4, 4)
        rate = float(data.get("rate_hz", 30.0))
    except (TypeError, ValueError):
        raise ValueError(f"{source}: 'T_BS' data and 'rate_hz' must be numbers") from None
    try:
        return CameraModel(
            width=int(res[0]),
            height=int(res[1]),
            fu=fu,
            fv=fv,
            cu=cu,
            cv=cv_,
            distortion_model=dist_model,
            distortion=np.array(dist),
            T_body_camera=T,
            rate_hz=rate,
        )
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def sensor_from_camera(cam: CameraModel) -> dict[str, Any]:
    """The EuRoC `sensor.yaml` mapping of a camera (inverse of `camera_from_sensor`)."""
    return {
        "sensor_type": "camera",
        "comment": "irloc upward IR camera",
        "T_BS": {"rows": 4, "cols": 4, "data": [float(x) for x in cam.T_body_camera.reshape(-1)]},
        "rate_hz": float(cam.rate_hz),
        "resolution": [int(cam.width), int(cam.height)],
        "camera_model": "pinhole",
        "intrinsics": [float(cam.fu), float(cam.fv), float(cam.cu), float(cam.cv)],
        "distortion_model": cam.distortion_model,
        "distortion_coefficients": [float(x) for x in cam.distortion],
    }


def T_body_camera_upward(
    *,
    yaw: float = 0.0,
    offset_xy: tuple[float, float] = (0.0, 0.0),
    height: float = 0.3,
    tilt_xy: tuple[float, float] = (0.0, 0.0),
) -> FloatArray:
    """Mounting of an upward-looking camera, shape (4, 4).

    With yaw = 0 the camera's x axis (image right) points along body +y (the robot's left) and
    its y axis (image down) along body -x, so the image top is the robot's front, as one sees
    the ceiling looking up; its z axis (optical axis) points up.

    Args:
        yaw: rotation of the camera about the body's vertical axis, radians.
        offset_xy: optical centre's offset from the axle midpoint in the body frame, metres.
        height: optical centre's height above the floor, metres.
        tilt_xy: small rotations about body x then body y, radians (a mis-mounted camera).
    """
    R_up = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    cz, sz = math.cos(yaw), math.sin(yaw)
    Rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    ax, ay = tilt_xy
    Rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    Ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    T = np.eye(4)
    T[:3, :3] = Ry @ Rx @ Rz @ R_up
    T[:3, 3] = [offset_xy[0], offset_xy[1], height]
    return T
