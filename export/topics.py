"""Topic names and frame IDs of an export, one place for both profiles, the tests and docs.

Frames (REP-105): `map` (the landmark map's world frame), `odom` (wheel odometry from the
first sample), `base_link` (the robot's body, REP-103: x forward, y left, z up, on the
floor between the wheels), `camera` (the upward camera's OpenCV optical frame: x right,
y down, z along the optical axis, the ROS `_optical_frame` convention).
"""

from __future__ import annotations

from typing import Literal

Profile = Literal["foxglove", "ros2"]
PROFILES: tuple[Profile, ...] = ("foxglove", "ros2")

MAP, ODOM, BASE, CAMERA = "map", "odom", "base_link", "camera"

# topic -> (foxglove schema, ROS 2 type); None where a profile has no such topic
TOPICS: dict[str, dict[Profile, str]] = {
    "/cam0/image/compressed": {
        "foxglove": "foxglove.CompressedImage",
        "ros2": "sensor_msgs/msg/CompressedImage",
    },
    "/cam0/camera_info": {
        "foxglove": "foxglove.CameraCalibration",
        "ros2": "sensor_msgs/msg/CameraInfo",
    },
    "/cam0/annotations": {
        "foxglove": "foxglove.ImageAnnotations",
        "ros2": "visualization_msgs/msg/ImageMarker",
    },
    "/irloc/pose": {
        "foxglove": "foxglove.PoseInFrame",
        "ros2": "geometry_msgs/msg/PoseWithCovarianceStamped",
    },
    "/irloc/pose_with_covariance": {"foxglove": "foxglove.Odometry"},
    "/irloc/uncertainty": {"foxglove": "foxglove.SceneUpdate"},
    "/irloc/mode": {"foxglove": "foxglove.Log", "ros2": "std_msgs/msg/String"},
    "/tf": {"foxglove": "foxglove.FrameTransforms", "ros2": "tf2_msgs/msg/TFMessage"},
    "/tf_static": {"foxglove": "foxglove.FrameTransforms", "ros2": "tf2_msgs/msg/TFMessage"},
    "/odom": {"foxglove": "foxglove.Odometry", "ros2": "nav_msgs/msg/Odometry"},
    "/landmarks": {
        "foxglove": "foxglove.SceneUpdate",
        "ros2": "visualization_msgs/msg/MarkerArray",
    },
    "/groundtruth": {"foxglove": "foxglove.PoseInFrame", "ros2": "geometry_msgs/msg/PoseStamped"},
}


def topics(profile: Profile) -> dict[str, str]:
    """topic -> schema name of a profile."""
    return {t: p[profile] for t, p in TOPICS.items() if profile in p}


LIT_RGBA = (1.0, 0.85, 0.1, 1.0)
"""Landmark colour when its LED is lit (amber)."""
DARK_RGBA = (0.35, 0.35, 0.4, 1.0)
"""Landmark colour when its LED is dark (grey)."""
SPOT_RGBA = (0.2, 0.9, 1.0, 1.0)
"""Detected spots on the image (cyan)."""
USED_RGBA = (0.2, 1.0, 0.3, 1.0)
"""Landmarks the localizer used, where it predicts them (green)."""
LANDMARK_DIAMETER_M = 0.08
