"""Write a recording folder (docs/recording.md): the simulator's output and
the live recorder's.

The static files (map.json, robot.yaml, cam0/sensor.yaml) are written when the writer is
made; the CSV files grow line by line. Timestamps must not go backwards within a file.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Iterable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from types import TracebackType
from typing import Any, TextIO

import cv2
import numpy as np
import yaml

from localizer.camera import CameraModel, sensor_from_camera
from localizer.events import LedsChanged, NoPose, PoseEstimate
from localizer.landmark_map import LandmarkMap
from localizer.robot import RobotGeometry
from localizer.types import ImageU8
from recording import layout, poses_file
from recording.start_pose import StartPose, write_start_pose


def _number(v: float) -> str:
    """Shortest text that reads back to the same float."""
    return repr(float(v))


class _CsvFile:
    """One CSV file of the recording, opened lazily, timestamps checked non-decreasing."""

    def __init__(self, path: Path, header: str) -> None:
        self.path = path
        self.header = header
        self._file: TextIO | None = None
        self._last_t_ns = -1

    def write(self, t_ns: int, fields: Iterable[str]) -> None:
        t = int(t_ns)
        if t < 0 or t < self._last_t_ns:
            raise ValueError(f"{self.path}: timestamp {t} is before {self._last_t_ns} or negative")
        file = self.open_empty()
        self._last_t_ns = t
        file.write(",".join([str(t), *fields]) + "\n")

    def open_empty(self) -> TextIO:
        """Create the file with its header (if not yet open) and return it."""
        if self._file is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("w", encoding="utf-8", newline="\n")
            self._file.write(self.header + "\n")
        return self._file

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


class RecordingWriter:
    """Write one recording folder.

    Args:
        root: the folder (created; existing files of the same names are overwritten).
        camera: the nominal camera, written to cam0/sensor.yaml.
        robot: the wheel geometry, written to robot.yaml.
        landmark_records: map.json's landmark objects (`id`, `x`, `y`, `z`, extra keys kept).
        png_compression: zlib level of the PNGs, 0-9 (Huffman-only: fast, and the frames'
            sensor noise defeats the rest of deflate anyway).
        png_threads: PNGs are encoded on this many threads (OpenCV releases the GIL).

    Raises:
        ValueError: the landmark records do not make a valid map.
    """

    def __init__(
        self,
        root: Path | str,
        camera: CameraModel,
        robot: RobotGeometry,
        landmark_records: Iterable[Mapping[str, Any]],
        *,
        png_compression: int = 3,
        png_threads: int = 2,
    ) -> None:
        self.root = Path(root)
        self.png_compression = png_compression
        self._pool_workers = max(png_threads, 1)
        self._pool = ThreadPoolExecutor(self._pool_workers, thread_name_prefix="png")
        self._pending: deque[Future[None]] = deque()
        records = [dict(r) for r in landmark_records]
        self.landmark_map = LandmarkMap.from_records(records, source="landmark_records")
        (self.root / layout.FRAMES_DIR).mkdir(parents=True, exist_ok=True)
        (self.root / layout.MAP_FILE).write_text(
            json.dumps({"landmarks": records}, indent=1) + "\n", encoding="utf-8"
        )
        robot_data = {"wheel_base": float(robot.wheel_base), "max_speed": float(robot.max_speed)}
        (self.root / layout.ROBOT_FILE).write_text(
            yaml.safe_dump(robot_data, sort_keys=False), encoding="utf-8"
        )
        (self.root / layout.SENSOR_FILE).write_text(
            yaml.safe_dump(sensor_from_camera(camera), sort_keys=False, default_flow_style=None),
            encoding="utf-8",
        )
        self._frames = _CsvFile(self.root / layout.FRAMES_FILE, layout.FRAMES_HEADER)
        self._odometry = _CsvFile(self.root / layout.ODOMETRY_FILE, layout.ODOMETRY_HEADER)
        self._leds = _CsvFile(self.root / layout.LEDS_FILE, layout.LEDS_HEADER)
        self._groundtruth = _CsvFile(self.root / layout.GROUNDTRUTH_FILE, layout.GROUNDTRUTH_HEADER)
        self._live_poses = _CsvFile(self.root / layout.LIVE_POSES_FILE, poses_file.HEADER)
        self._imu = _CsvFile(self.root / layout.IMU_FILE, layout.IMU_HEADER)
        for f in (self._frames, self._odometry, self._leds):
            f.open_empty()

    def add_frame(self, t_ns: int, image: ImageU8) -> Path:
        """Write an 8-bit grayscale frame as `cam0/data/<t_ns>.png` and list it; returns the path.

        Raises:
            ValueError: the image is not a 2-D uint8 array, or time went backwards.
        """
        img = np.asarray(image)
        if img.dtype != np.uint8 or img.ndim != 2:
            raise ValueError(
                f"frame {t_ns}: expected a 2-D uint8 image, got {img.dtype} {img.shape}"
            )
        name = f"{int(t_ns)}.png"
        self._frames.write(t_ns, [name])
        path = self.root / layout.FRAMES_DIR / name
        while len(self._pending) >= 2 * self._pool_workers:
            self._pending.popleft().result()
        self._pending.append(self._pool.submit(self._write_png, path, img.copy()))
        return path

    def _write_png(self, path: Path, image: ImageU8) -> None:
        params = [
            cv2.IMWRITE_PNG_COMPRESSION,
            self.png_compression,
            cv2.IMWRITE_PNG_STRATEGY,
            cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY,
        ]
        if not cv2.imwrite(str(path), image, params):
            raise OSError(f"{path}: could not write the PNG")

    def add_odometry(self, t_ns: int, v_left: float, v_right: float) -> None:
        """Add measured wheel speeds (m/s) at `t_ns`."""
        self._odometry.write(t_ns, [_number(v_left), _number(v_right)])

    def add_imu(
        self, t_ns: int, gyro: tuple[float, float, float], accel: tuple[float, float, float]
    ) -> None:
        """Add an IMU sample to imu0/data.csv (EuRoC layout; the IMU's axes are the body's:
        imu0/sensor.yaml holds an identity T_BS, written with the first sample)."""
        if not (self.root / layout.IMU_SENSOR_FILE).exists():
            self._imu.path.parent.mkdir(parents=True, exist_ok=True)
            sensor = {
                "sensor_type": "imu",
                "T_BS": {"rows": 4, "cols": 4, "data": np.eye(4).reshape(-1).tolist()},
            }
            (self.root / layout.IMU_SENSOR_FILE).write_text(
                yaml.safe_dump(sensor, sort_keys=False, default_flow_style=None), encoding="utf-8"
            )
        self._imu.write(t_ns, [_number(v) for v in (*gyro, *accel)])

    def set_start_pose(
        self,
        x: float,
        y: float,
        theta: float,
        radius_m: float | None = None,
        t_ns: int | None = None,
    ) -> None:
        """Write start_pose.yaml: where the robot starts (a prior for the localizer; metres,
        radians, the search radius in metres, when it holds).

        Raises:
            ValueError: a value `StartPose` refuses.
        """
        write_start_pose(self.root, StartPose(x, y, theta, radius_m, t_ns))

    def add_leds(self, event: LedsChanged) -> None:
        """Add the LED state in force from `event.t_ns` on. A landmark the event lists as
        `changing` (its command in flight: the radio has not confirmed it) is written lit
        (`LedsChanged.surely_dark_as_dark`): a dark landmark in leds.csv is dark in every
        frame of that time, whenever the LED actually switched.

        Raises:
            ValueError: a lit ID is not in the map.
        """
        event = event.surely_dark_as_dark()
        unknown = sorted(i for i in event.lit if i not in self.landmark_map)
        if unknown:
            raise ValueError(f"leds: landmarks {unknown} are not in the map")
        if event.all_lit or (event.lit and len(event.lit) == len(self.landmark_map)):
            on = layout.LEDS_ALL
        elif not event.lit:
            on = layout.LEDS_NONE
        else:
            on = " ".join(str(i) for i in sorted(event.lit))
        self._leds.write(event.t_ns, [on])

    def add_groundtruth(self, t_ns: int, x: float, y: float, theta: float) -> None:
        """Add the true body pose at `t_ns` to groundtruth.csv (simulated recordings)."""
        self._groundtruth.write(t_ns, [_number(x), _number(y), _number(theta)])

    def add_pose(self, estimate: PoseEstimate | NoPose) -> None:
        """Add the live localizer's output for a recorded frame to live_poses.csv (live
        recordings: what the robot believed, beside what a replay would give)."""
        t, *fields = poses_file.format_row(estimate).split(",")
        self._live_poses.write(int(t), fields)

    def close(self) -> None:
        """Finish writing the PNGs, flush and close every file; idempotent.

        Raises:
            OSError: a PNG could not be written.
        """
        try:
            while self._pending:
                self._pending.popleft().result()
        finally:
            self._pool.shutdown(wait=True)
        for f in (
            self._frames,
            self._odometry,
            self._leds,
            self._groundtruth,
            self._live_poses,
            self._imu,
        ):
            f.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
