"""File names and CSV headers of a recording (docs/recording.md), shared by
the reader and the writer.
"""

from __future__ import annotations

MAP_FILE = "map.json"
ROBOT_FILE = "robot.yaml"
SENSOR_FILE = "cam0/sensor.yaml"
FRAMES_FILE = "cam0/data.csv"
FRAMES_DIR = "cam0/data"
ODOMETRY_FILE = "odom0/data.csv"
LEDS_FILE = "leds.csv"
GROUNDTRUTH_FILE = "groundtruth.csv"
LIVE_POSES_FILE = "live_poses.csv"

FRAMES_HEADER = "#timestamp [ns],filename"
ODOMETRY_HEADER = "#timestamp [ns],v_left [m/s],v_right [m/s]"
LEDS_HEADER = "#timestamp [ns],on"
GROUNDTRUTH_HEADER = "timestamp_ns,x,y,theta"

LEDS_ALL = "all"
LEDS_NONE = "none"
