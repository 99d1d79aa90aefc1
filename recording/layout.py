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
START_POSE_FILE = "start_pose.yaml"
IMU_FILE = "imu0/data.csv"
IMU_SENSOR_FILE = "imu0/sensor.yaml"

FRAMES_HEADER = "#timestamp [ns],filename"
ODOMETRY_HEADER = "#timestamp [ns],v_left [m/s],v_right [m/s]"
LEDS_HEADER = "#timestamp [ns],on"
GROUNDTRUTH_HEADER = "timestamp_ns,x,y,theta"
IMU_HEADER = (
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]"
)  # EuRoC's imu0/data.csv

LEDS_ALL = "all"
LEDS_NONE = "none"
