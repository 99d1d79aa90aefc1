"""Frames from ROS 2 image messages: compressed PNG/JPEG (8 and 16 bit) and what is refused."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ros2.images import ImageError, gray8_from_compressed, gray8_from_image
from ros2.messages import new

GRAY = (np.arange(48 * 64).reshape(48, 64) % 251).astype(np.uint8)


def compressed(fmt: str, data: bytes) -> object:
    return new("sensor_msgs/msg/CompressedImage", format=fmt, data=data)


def test_png_and_jpeg_as_image_transport_writes_them() -> None:
    png = cv2.imencode(".png", GRAY)[1].tobytes()
    np.testing.assert_array_equal(
        gray8_from_compressed(compressed("mono8; png compressed", png)), GRAY
    )
    wide = cv2.imencode(".png", GRAY.astype(np.uint16) << 8)[1].tobytes()
    np.testing.assert_array_equal(
        gray8_from_compressed(compressed("mono16; png compressed", wide)), GRAY
    )
    jpeg = cv2.imencode(
        ".jpg", cv2.cvtColor(GRAY, cv2.COLOR_GRAY2BGR), [cv2.IMWRITE_JPEG_QUALITY, 100]
    )[1]
    out = gray8_from_compressed(compressed("bgr8; jpeg compressed bgr8", jpeg.tobytes()))
    assert out.shape == GRAY.shape and np.abs(out.astype(int) - GRAY).max() <= 3


def test_what_cannot_be_read_is_refused_with_its_reason() -> None:
    with pytest.raises(ImageError, match="is not PNG or JPEG"):
        gray8_from_compressed(compressed("theora", b"x"))
    with pytest.raises(ImageError, match="does not decode"):
        gray8_from_compressed(compressed("png", b"not a png"))
    png = cv2.imencode(".png", GRAY)[1].tobytes()
    with pytest.raises(ImageError, match="calibrated for 640x480"):
        gray8_from_compressed(compressed("png", png), expected_size=(640, 480))
    big_endian = new(
        "sensor_msgs/msg/Image", height=48, width=64, encoding="mono16", is_bigendian=1, step=128,
        data=(GRAY.astype(">u2") << 8).astype(">u2").tobytes(),
    )  # fmt: skip
    np.testing.assert_array_equal(gray8_from_image(big_endian), GRAY)
