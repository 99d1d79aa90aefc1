"""Read a recording folder (docs/recording.md) into arrays and events.

Nothing here decodes PNGs: frames are listed as `FrameEntry` (time, path, line of
`cam0/data.csv`) and the caller decodes them when it gets there, so a long recording costs
little memory and a listed file that cannot be read is the caller's to report.

Every file problem raises `RecordingError`, whose message reads "FILE:LINE: what is wrong"
(or "FILE: what is wrong" when no line applies).
"""

from __future__ import annotations

import heapq
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from localizer.camera import CameraModel, camera_from_sensor
from localizer.events import ImuMeasured, LedsChanged, OdometryMeasured
from localizer.landmark_map import LandmarkMap
from localizer.robot import RobotGeometry, robot_from_yaml_dict
from localizer.types import FloatArray, IntArray
from recording import layout
from recording.start_pose import StartPose, start_pose_from_dict

T = TypeVar("T")


class RecordingError(ValueError):
    """A recording file is missing or malformed.

    Attributes:
        file: the file's path.
        line: 1-based line number, or None when the problem is not on one line.
    """

    def __init__(self, file: Path | str, line: int | None, what: str) -> None:
        self.file = str(file)
        self.line = line
        self.what = what
        where = self.file if line is None else f"{self.file}:{line}"
        super().__init__(f"{where}: {what}")


@dataclass(frozen=True)
class FrameEntry:
    """One line of `cam0/data.csv`.

    Attributes:
        t_ns: the frame's timestamp, ns.
        path: the PNG file (it may be missing or unreadable).
        line: the line of `cam0/data.csv` that lists it, 1-based.
    """

    t_ns: int
    path: Path
    line: int


@dataclass(frozen=True, eq=False)
class Recording:
    """A whole recording, frames not decoded.

    Attributes:
        root: the recording folder.
        landmark_map: the surveyed map.
        landmark_records: map.json's landmark objects as read, extra keys (e.g. `radio`) kept.
        robot: wheel geometry.
        camera: the nominal camera (cam0/sensor.yaml).
        frames: in file order (timestamps non-decreasing).
        odom_t_ns: odometry timestamps, ns, int64 shape (N,).
        odom_v: measured wheel speeds (v_left, v_right), m/s, shape (N, 2).
        leds: LED states in force from their timestamps on, in time order.
        start_pose: the prior on the start pose (`start_pose.yaml`), None without one.
        imu_t_ns: IMU timestamps, ns, int64 shape (M,) (empty without `imu0/data.csv`).
        imu: body-frame gyro (rad/s) and specific force (m/s^2), shape (M, 6):
            (wx, wy, wz, ax, ay, az), rotated from the IMU's frame by `imu0/sensor.yaml`'s
            T_BS (identity without one).
    """

    root: Path
    landmark_map: LandmarkMap
    landmark_records: list[dict[str, Any]]
    robot: RobotGeometry
    camera: CameraModel
    frames: list[FrameEntry]
    odom_t_ns: IntArray
    odom_v: FloatArray
    leds: list[LedsChanged]
    start_pose: StartPose | None = None
    imu_t_ns: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))
    imu: FloatArray = field(default_factory=lambda: np.zeros((0, 6)))


Item = OdometryMeasured | ImuMeasured | LedsChanged | FrameEntry


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RecordingError(path, None, "missing file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(path, None, f"cannot read: {exc}") from None


def _data_lines(path: Path) -> Iterator[tuple[int, list[str]]]:
    """(1-based line number, comma-separated fields) of every non-blank, non-# line."""
    text = _read_text(path)
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield number, [f.strip() for f in line.split(",")]


def _fields(path: Path, number: int, fields: list[str], count: int, names: str) -> list[str]:
    if len(fields) < count:
        raise RecordingError(path, number, f"expected {count} fields ({names}), got {fields}")
    return fields[:count]


def _timestamp(path: Path, number: int, text: str, previous: int) -> int:
    try:
        t_ns = int(text)
    except ValueError:
        raise RecordingError(path, number, f"timestamp must be integer ns, got {text!r}") from None
    if t_ns < 0:
        raise RecordingError(path, number, f"timestamp must be >= 0, got {t_ns}")
    if t_ns < previous:
        raise RecordingError(path, number, f"timestamp {t_ns} is earlier than {previous}")
    return t_ns


MAX_WHEEL_SPEED_M_S = 20.0
"""Wheel speeds beyond this are not a robot's (the server's serial lines use the same bound)."""
MAX_ABS_XY_M = 10_000.0
"""Positions beyond this are not on a site (the map's own bound)."""
MAX_ABS_THETA_RAD = 1_000.0


def _finite(path: Path, number: int, text: str, name: str, limit: float = math.inf) -> float:
    """A finite number of at most `limit` in magnitude; RecordingError naming it otherwise."""
    try:
        v = float(text)
    except ValueError:
        raise RecordingError(path, number, f"{name} must be a number, got {text!r}") from None
    if not math.isfinite(v):
        raise RecordingError(path, number, f"{name} must be finite, got {text!r}")
    if abs(v) > limit:
        raise RecordingError(path, number, f"{name} {text} is beyond +-{limit:g} (SI units)")
    return v


def load_structured(path: Path, loader: Callable[[str], Any]) -> Any:
    """A JSON or YAML file parsed by `loader`; RecordingError naming the file (and line)."""
    text = _read_text(path)
    try:
        return loader(text)
    except json.JSONDecodeError as exc:
        raise RecordingError(path, exc.lineno, f"invalid JSON: {exc.msg}") from None
    except yaml.MarkedYAMLError as exc:
        line = exc.problem_mark.line + 1 if exc.problem_mark is not None else None
        raise RecordingError(path, line, f"invalid YAML: {exc.problem}") from None
    except yaml.YAMLError as exc:
        raise RecordingError(path, None, f"invalid YAML: {exc}") from None


def _checked(path: Path, build: Callable[[], T]) -> T:
    """Run a builder that raises ValueError prefixed "PATH: ", re-raised as RecordingError."""
    try:
        return build()
    except ValueError as exc:
        what = str(exc).removeprefix(f"{path}: ")
        raise RecordingError(path, None, what) from None


def read_map(path: Path) -> tuple[LandmarkMap, list[dict[str, Any]]]:
    """map.json -> (map, the landmark objects as read)."""
    data = load_structured(path, json.loads)
    if not isinstance(data, dict) or not isinstance(data.get("landmarks"), list):
        raise RecordingError(path, None, "expected an object with a 'landmarks' list")
    records = data["landmarks"]
    landmark_map = _checked(path, lambda: LandmarkMap.from_records(records, source=str(path)))
    return landmark_map, [dict(r) for r in records]


def read_frames(path: Path, frames_dir: Path) -> list[FrameEntry]:
    """cam0/data.csv -> frame entries (paths inside `frames_dir`)."""
    out: list[FrameEntry] = []
    previous = 0
    for number, fields in _data_lines(path):
        t_text, name = _fields(path, number, fields, 2, "timestamp, filename")
        previous = _timestamp(path, number, t_text, previous)
        if not name:
            raise RecordingError(path, number, "empty filename")
        out.append(FrameEntry(previous, frames_dir / name, number))
    return out


def read_odometry(path: Path) -> tuple[IntArray, FloatArray]:
    """odom0/data.csv -> (t_ns (N,), (v_left, v_right) (N, 2)); empty when the file is absent."""
    if not path.exists():
        return np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    times: list[int] = []
    speeds: list[tuple[float, float]] = []
    previous = 0
    for number, fields in _data_lines(path):
        t_text, vl, vr = _fields(path, number, fields, 3, "timestamp, v_left, v_right")
        previous = _timestamp(path, number, t_text, previous)
        times.append(previous)
        lim = MAX_WHEEL_SPEED_M_S
        speeds.append(
            (
                _finite(path, number, vl, "v_left", lim),
                _finite(path, number, vr, "v_right", lim),
            )
        )
    return np.array(times, dtype=np.int64), np.array(speeds, dtype=np.float64).reshape(-1, 2)


def read_start_pose(path: Path) -> StartPose | None:
    """start_pose.yaml -> the start-pose prior; None when the file is absent."""
    if not path.exists():
        return None
    data = load_structured(path, yaml.safe_load)
    try:
        return start_pose_from_dict(data)
    except ValueError as exc:
        raise RecordingError(path, None, str(exc)) from None


def read_imu(path: Path, sensor_path: Path) -> tuple[IntArray, FloatArray]:
    """imu0/data.csv (EuRoC: t, w_x, w_y, w_z, a_x, a_y, a_z in the IMU frame) -> (t_ns (M,),
    body-frame (w, a) (M, 6)) rotated by imu0/sensor.yaml's T_BS when present; empty when
    the data file is absent."""
    if not path.exists():
        return np.zeros(0, dtype=np.int64), np.zeros((0, 6))
    R = np.eye(3)
    if sensor_path.exists():
        data = load_structured(sensor_path, yaml.safe_load)
        T_BS = data.get("T_BS") if isinstance(data, dict) else None
        values = T_BS.get("data") if isinstance(T_BS, dict) else None
        if not isinstance(values, list) or len(values) != 16:
            raise RecordingError(sensor_path, None, "'T_BS' must be a 4x4 mapping of 16 numbers")
        try:
            R = np.array([float(v) for v in values]).reshape(4, 4)[:3, :3]
        except (TypeError, ValueError):
            raise RecordingError(sensor_path, None, "'T_BS' data must be numbers") from None
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6):
            raise RecordingError(sensor_path, None, "'T_BS' rotation is not orthonormal")
    names = ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z")
    times: list[int] = []
    rows: list[list[float]] = []
    previous = 0
    for number, fields in _data_lines(path):
        t_text, *values_text = _fields(path, number, fields, 7, "timestamp, " + ", ".join(names))
        previous = _timestamp(path, number, t_text, previous)
        times.append(previous)
        rows.append([_finite(path, number, v, n) for v, n in zip(values_text, names, strict=True)])
    raw = np.array(rows, dtype=np.float64).reshape(-1, 6)
    body = np.hstack([raw[:, :3] @ R.T, raw[:, 3:] @ R.T])
    return np.array(times, dtype=np.int64), body


def read_leds(path: Path, landmark_map: LandmarkMap) -> list[LedsChanged]:
    """leds.csv -> LED states; empty when the file is absent. Unknown IDs are errors."""
    if not path.exists():
        return []
    out: list[LedsChanged] = []
    previous = 0
    for number, fields in _data_lines(path):
        t_text, on = _fields(path, number, fields, 2, "timestamp, on")
        previous = _timestamp(path, number, t_text, previous)
        if on == layout.LEDS_ALL:
            out.append(LedsChanged(previous, all_lit=True))
            continue
        if on == layout.LEDS_NONE:
            out.append(LedsChanged(previous))
            continue
        lit: set[int] = set()
        for token in on.split():
            try:
                lid = int(token)
            except ValueError:
                raise RecordingError(
                    path, number, f"expected 'all', 'none' or landmark IDs, got {token!r}"
                ) from None
            if lid not in landmark_map:
                raise RecordingError(path, number, f"landmark {lid} is not in the map")
            lit.add(lid)
        if not lit:
            raise RecordingError(path, number, "empty LED state (write 'none')")
        out.append(LedsChanged(previous, frozenset(lit)))
    return out


def read_groundtruth(root: Path | str) -> tuple[IntArray, FloatArray]:
    """groundtruth.csv of a simulated recording -> (t_ns (N,), (x, y, theta) (N, 3))."""
    return read_groundtruth_file(Path(root) / layout.GROUNDTRUTH_FILE)


def read_groundtruth_file(
    path: Path | str,
) -> tuple[IntArray, FloatArray]:
    """A ground-truth CSV (`timestamp_ns,x,y,theta`, header optional) anywhere -> (t_ns (N,),
    (x, y, theta) (N, 3)); RecordingError naming the file and line of a bad value."""
    path = Path(path)
    times: list[int] = []
    poses: list[tuple[float, float, float]] = []
    previous = 0
    for number, fields in _data_lines(path):
        if number == 1 and fields[0] == "timestamp_ns":
            continue
        t_text, x, y, th = _fields(path, number, fields, 4, "timestamp_ns, x, y, theta")
        previous = _timestamp(path, number, t_text, previous)
        times.append(previous)
        poses.append(
            (
                _finite(path, number, x, "x", MAX_ABS_XY_M),
                _finite(path, number, y, "y", MAX_ABS_XY_M),
                _finite(path, number, th, "theta", MAX_ABS_THETA_RAD),
            )
        )
    return np.array(times, dtype=np.int64), np.array(poses, dtype=np.float64).reshape(-1, 3)


def read_recording(root: Path | str) -> Recording:
    """Read a recording folder (frames listed, not decoded).

    Required: map.json, robot.yaml, cam0/sensor.yaml, cam0/data.csv. odom0/data.csv,
    leds.csv, imu0/data.csv and start_pose.yaml may be absent (no odometry; no LED
    information; no IMU; no start pose). Extra files and extra CSV columns
    are ignored.

    Raises:
        RecordingError: naming the file (and line) of the first problem found.
    """
    base = Path(root)
    if not base.is_dir():
        raise RecordingError(base, None, "not a recording folder")
    landmark_map, records = read_map(base / layout.MAP_FILE)
    robot_path = base / layout.ROBOT_FILE
    robot_data = load_structured(robot_path, yaml.safe_load)
    robot = _checked(robot_path, lambda: robot_from_yaml_dict(robot_data, source=str(robot_path)))
    sensor_path = base / layout.SENSOR_FILE
    sensor_data = load_structured(sensor_path, yaml.safe_load)
    camera = _checked(sensor_path, lambda: camera_from_sensor(sensor_data, source=str(sensor_path)))
    frames = read_frames(base / layout.FRAMES_FILE, base / layout.FRAMES_DIR)
    odom_t_ns, odom_v = read_odometry(base / layout.ODOMETRY_FILE)
    leds = read_leds(base / layout.LEDS_FILE, landmark_map)
    start_pose = read_start_pose(base / layout.START_POSE_FILE)
    imu_t_ns, imu = read_imu(base / layout.IMU_FILE, base / layout.IMU_SENSOR_FILE)
    return Recording(
        root=base,
        landmark_map=landmark_map,
        landmark_records=records,
        robot=robot,
        camera=camera,
        frames=frames,
        odom_t_ns=odom_t_ns,
        odom_v=odom_v,
        leds=leds,
        start_pose=start_pose,
        imu_t_ns=imu_t_ns,
        imu=imu,
    )


def iter_timeline(recording: Recording) -> Iterator[Item]:
    """Odometry samples, LED changes and frame entries merged into one time-ordered stream.

    At equal timestamps odometry comes first, then IMU samples, LED changes, the frame (a
    frame shows the LED state in force at its timestamp and the pose with odometry
    integrated up to it).
    Frames are yielded as `FrameEntry`; the caller decodes the PNG.
    """

    def odometry() -> Iterator[tuple[int, int, Item]]:
        for t, (vl, vr) in zip(
            recording.odom_t_ns.tolist(), recording.odom_v.tolist(), strict=True
        ):
            yield t, 0, OdometryMeasured(t, vl, vr)

    def imu() -> Iterator[tuple[int, int, Item]]:
        for t, r in zip(recording.imu_t_ns.tolist(), recording.imu.tolist(), strict=True):
            yield t, 1, ImuMeasured(t, (r[0], r[1], r[2]), (r[3], r[4], r[5]))

    leds = ((e.t_ns, 2, e) for e in recording.leds)
    frames = ((f.t_ns, 3, f) for f in recording.frames)
    streams = (odometry(), imu(), leds, frames)
    for _, _, item in heapq.merge(*streams, key=lambda x: (x[0], x[1])):
        yield item
