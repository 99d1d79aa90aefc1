"""From a recording of a survey drive to the estimator's problem: decode each frame, detect
its spots (`localizer.spots.detect_spots`), carry them between frames with the wheels and name
them by the LED blinks (`survey.observations`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from localizer.camera import CameraModel, camera_from_sensor
from localizer.events import LedsChanged
from localizer.landmark_map import LandmarkMap
from localizer.robot import RobotGeometry, robot_from_yaml_dict
from localizer.spots import DetectionConfig, detect_spots
from localizer.types import FloatArray, IntArray
from recording import layout
from recording.reader import read_frames, read_leds, read_odometry
from survey.observations import TrackingConfig, label_spot_tracks
from survey.odometry_chain import relative_motions, wheel_intervals
from survey.problem import SurveyProblem
from survey.survey_map import SurveyLandmark, read_survey_map


@dataclass(frozen=True, eq=False)
class SurveyDrive:
    """A survey recording, read.

    Attributes:
        landmarks: the input map's landmarks.
        camera, robot: from cam0/sensor.yaml and robot.yaml.
        frame_t_ns: times of the frames that could be read, shape (F,).
        frame_spots: their spots' pixels, each (N_f, 2).
        odom_t_ns, odom_v: wheel speeds.
        leds: LED states.
        unreadable: frames listed but not readable.
    """

    landmarks: list[SurveyLandmark]
    camera: CameraModel
    robot: RobotGeometry
    frame_t_ns: IntArray
    frame_spots: list[FloatArray]
    odom_t_ns: IntArray
    odom_v: FloatArray
    leds: list[LedsChanged]
    unreadable: int


def _yaml(path: Path) -> Any:
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: missing") from None
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read it ({exc})") from None


def _threads() -> int:
    cores = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    return max(1, len(cores) if cores else (os.cpu_count() or 1))


def _spots_of(path: Path, config: DetectionConfig) -> FloatArray | None:
    """The spots of one frame file, or None when it cannot be read."""
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        return None
    return detect_spots(np.asarray(image, dtype=np.uint8), config).pixels


def read_survey_drive(
    root: Path,
    *,
    detection: DetectionConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SurveyDrive:
    """Read a survey recording and detect the spots of every frame.

    Raises:
        ValueError: naming the file and what is wrong (RecordingError is one).
    """
    if not root.is_dir():
        raise ValueError(f"{root}: not a recording folder")
    landmarks = read_survey_map(root / layout.MAP_FILE)
    robot = robot_from_yaml_dict(
        _yaml(root / layout.ROBOT_FILE), source=str(root / layout.ROBOT_FILE)
    )
    camera = camera_from_sensor(
        _yaml(root / layout.SENSOR_FILE), source=str(root / layout.SENSOR_FILE)
    )
    frames = read_frames(root / layout.FRAMES_FILE, root / layout.FRAMES_DIR)
    odom_t, odom_v = read_odometry(root / layout.ODOMETRY_FILE)
    ids_map = LandmarkMap(np.array([lm.id for lm in landmarks]), np.zeros((len(landmarks), 3)))
    leds = read_leds(root / layout.LEDS_FILE, ids_map)
    cfg = detection or DetectionConfig()
    times: list[int] = []
    spots: list[FloatArray] = []
    unreadable = 0
    last_t: int | None = None
    with ThreadPoolExecutor(max_workers=_threads()) as pool:  # OpenCV releases the GIL
        for i, (entry, found) in enumerate(
            zip(frames, pool.map(lambda e: _spots_of(e.path, cfg), frames), strict=True)
        ):
            if progress is not None and i % 200 == 0:
                progress(i, len(frames))
            if found is None:
                unreadable += 1
                continue
            if last_t is not None and entry.t_ns <= last_t:
                continue
            times.append(entry.t_ns)
            spots.append(found)
            last_t = entry.t_ns
    if progress is not None:
        progress(len(frames), len(frames))
    return SurveyDrive(
        landmarks,
        camera,
        robot,
        np.asarray(times, dtype=np.int64),
        spots,
        odom_t,
        odom_v,
        leds,
        unreadable,
    )


def frame_motions(drive: SurveyDrive) -> FloatArray:
    """The wheels' motion from each frame to the next (nominal calibration), (F - 1, 3)."""
    if len(drive.odom_t_ns) == 0 or len(drive.frame_t_ns) < 2:
        return np.zeros((max(len(drive.frame_t_ns) - 1, 0), 3))
    wheels = wheel_intervals(drive.odom_t_ns, drive.odom_v, drive.frame_t_ns)
    return relative_motions(wheels, drive.robot.wheel_base)


def survey_problem(
    drive: SurveyDrive, anchors: Iterable[int], *, tracking: TrackingConfig | None = None
) -> SurveyProblem:
    """Name the spots and set up the estimation with `anchors` held at their positions.

    Raises:
        ValueError: an anchor not in the map or without a position, fewer than two anchors,
            or no odometry.
    """
    by_id = {lm.id: lm for lm in drive.landmarks}
    anchor_ids = list(dict.fromkeys(int(a) for a in anchors))
    for a in anchor_ids:
        if a not in by_id:
            raise ValueError(f"survey: anchor {a} is not in map.json")
        if by_id[a].position is None:
            raise ValueError(f"survey: anchor {a} has no position in map.json")
    if len(anchor_ids) < 2:
        raise ValueError(f"survey: needs two or more anchors (--anchor ID), got {len(anchor_ids)}")
    if len(drive.odom_t_ns) == 0:
        raise ValueError("survey: the recording has no odometry (odom0/data.csv missing or empty)")
    positioned = [lm.position[2] for lm in drive.landmarks if lm.position is not None]
    ceiling = float(np.median(positioned))
    obs = label_spot_tracks(
        drive.camera,
        list(by_id),
        drive.frame_t_ns.tolist(),
        drive.frame_spots,
        frame_motions(drive),
        drive.leds,
        ceiling_z_m=ceiling,
        config=tracking,
    )
    anchor_pos = {a: by_id[a].position for a in anchor_ids}
    return SurveyProblem(
        drive.camera,
        drive.robot.wheel_base,
        drive.frame_t_ns,
        obs,
        drive.odom_t_ns,
        drive.odom_v,
        {a: p for a, p in anchor_pos.items() if p is not None},
        {lm.id: lm.position for lm in drive.landmarks if lm.id not in anchor_pos},
    )
