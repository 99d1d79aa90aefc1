"""ROS 2 without rclpy: irloc on a ROS 2 graph as a DDS participant (the `cyclonedds` binding),
with message types generated from ROS 2's own definitions (`rosbags`). docs/ros2.md."""
