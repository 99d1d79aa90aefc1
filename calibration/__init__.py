"""Calibration of the upward camera: its lens (Zhang's method) and its mounting (T_BS)."""

from calibration.board import BoardCorners, BoardSpec, find_board, parse_pattern
from calibration.camera_pose import CameraPose, camera_pose_from_landmarks
from calibration.coverage import Coverage, corner_coverage
from calibration.lens import (
    LensCalibration,
    LensCalibrationConfig,
    ViewReport,
    calibrate_lens,
)
from calibration.mounting import (
    MountingCalibration,
    MountingConfig,
    estimate_mounting,
    mounting_from_observations,
)
from calibration.uploads import calibrate_from_uploads, decode_images

__all__ = [
    "BoardCorners",
    "BoardSpec",
    "CameraPose",
    "Coverage",
    "LensCalibration",
    "LensCalibrationConfig",
    "MountingCalibration",
    "MountingConfig",
    "ViewReport",
    "calibrate_from_uploads",
    "calibrate_lens",
    "camera_pose_from_landmarks",
    "corner_coverage",
    "decode_images",
    "estimate_mounting",
    "find_board",
    "mounting_from_observations",
    "parse_pattern",
]
