"""The generated types are ROS 2's: DDS type names by ROS 2's rule, and the same CDR bytes
as rosbags (rosbag2's serializer) writes for the same message."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from ros2.idl import dds_topic_name, dds_type_name, message_class, typestore
from ros2.messages import covariance3, covariance6, header, new, pose_msg, transform_stamped


def test_ros2_names() -> None:
    assert dds_type_name("geometry_msgs/msg/PoseWithCovarianceStamped") == (
        "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"
    )
    assert message_class("tf2_msgs/msg/TFMessage").__idl_typename__ == (
        "tf2_msgs::msg::dds_::TFMessage_"
    )
    assert dds_topic_name("/tf") == "rt/tf" and dds_topic_name("r1/odom") == "rt/r1/odom"
    with pytest.raises(ValueError, match="not valid"):
        dds_topic_name("/a//b")
    with pytest.raises(KeyError, match="not in ROS 2 Jazzy"):
        message_class("nope_msgs/msg/Nope")


def test_the_wire_bytes_are_rosbags_cdr() -> None:
    store = typestore()
    cov = np.diag([1e-4, 2e-4, 3e-5])
    messages = {
        "geometry_msgs/msg/PoseWithCovarianceStamped": new(
            "geometry_msgs/msg/PoseWithCovarianceStamped", header=header(1_700_000_000_123, "map"),
            pose=new("geometry_msgs/msg/PoseWithCovariance", pose=pose_msg((1.0, -2.0, 0.7)),
                     covariance=covariance6(cov)),
        ),
        "tf2_msgs/msg/TFMessage": new(
            "tf2_msgs/msg/TFMessage",
            transforms=[transform_stamped(5, "map", "r1/odom", (0.5, 0.25, -3.0))],
        ),
        "sensor_msgs/msg/Image": new(
            "sensor_msgs/msg/Image", header=header(7, "cam"), height=2, width=3,
            encoding="mono8", step=3, data=bytes([1, 2, 3, 4, 5, 6]),
        ),
        "std_msgs/msg/Empty": new("std_msgs/msg/Empty"),
    }  # fmt: skip
    for ros_type, msg in messages.items():
        ours = msg.serialize()
        theirs = store.deserialize_cdr(ours, ros_type)
        assert bytes(store.serialize_cdr(theirs, ros_type)) == ours, ros_type
    back: Any = store.deserialize_cdr(
        messages["geometry_msgs/msg/PoseWithCovarianceStamped"].serialize(),
        "geometry_msgs/msg/PoseWithCovarianceStamped",
    )
    np.testing.assert_allclose(covariance3(back.pose.covariance), cov)
    assert back.header.stamp.sec == 1700 and back.header.stamp.nanosec == 123
    image: Any = store.deserialize_cdr(
        messages["sensor_msgs/msg/Image"].serialize(), "sensor_msgs/msg/Image"
    )
    assert bytes(image.data) == bytes([1, 2, 3, 4, 5, 6])
