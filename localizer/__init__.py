"""IR ceiling-landmark localization (Sohn et al.), pure and sans-I/O: see docs/localizer.md."""

from localizer.camera import CameraModel, camera_from_sensor, predict_pixels
from localizer.config import FusionConfig, LocalizerConfig
from localizer.constellation import ConstellationConfig, ConstellationMatch, match_constellation
from localizer.events import (
    MODES,
    Event,
    FrameObserved,
    LedRequest,
    LedsChanged,
    Mode,
    NoPose,
    OdometryMeasured,
    Output,
    PoseEstimate,
    RelocalizeRequested,
    SpotsObserved,
)
from localizer.filter_config import FilterConfig
from localizer.handoff import HandoffConfig
from localizer.identification import IdentificationConfig, Identifier
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.passive_config import PassiveConfig
from localizer.pose import PoseFix, solve_pose
from localizer.pose_config import PoseSolveConfig
from localizer.pose_filter import PoseFilter
from localizer.pose_paper import pose_from_landmark_pair
from localizer.robot import RobotGeometry
from localizer.spot_windows import detect_spots_in_windows
from localizer.spots import DetectionConfig, Spots, detect_spots
from localizer.tracking import TrackingConfig, bottleneck_assignment

__all__ = [
    "MODES",
    "CameraModel",
    "ConstellationConfig",
    "ConstellationMatch",
    "DetectionConfig",
    "Event",
    "FilterConfig",
    "FrameObserved",
    "FusionConfig",
    "HandoffConfig",
    "IdentificationConfig",
    "Identifier",
    "LandmarkMap",
    "LedRequest",
    "LedsChanged",
    "Localizer",
    "LocalizerConfig",
    "Mode",
    "NoPose",
    "OdometryMeasured",
    "Output",
    "PassiveConfig",
    "PoseEstimate",
    "PoseFilter",
    "PoseFix",
    "PoseSolveConfig",
    "RelocalizeRequested",
    "RobotGeometry",
    "Spots",
    "SpotsObserved",
    "TrackingConfig",
    "bottleneck_assignment",
    "camera_from_sensor",
    "detect_spots",
    "detect_spots_in_windows",
    "match_constellation",
    "pose_from_landmark_pair",
    "predict_pixels",
    "solve_pose",
]
