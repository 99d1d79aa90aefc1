"""Camera frames from ROS 2 image messages: `sensor_msgs/Image` in the encodings an IR
camera driver publishes, and `sensor_msgs/CompressedImage` (PNG/JPEG, image_transport's
`compressed` plugin), to the 8-bit grayscale (H, W) the localizer detects spots in.

An image that cannot be what it says (wrong encoding, step or size) raises `ImageError`
naming the field and the values, and is never guessed at.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from localizer.types import ImageU8

_BAYER = {
    "bayer_rggb8": cv2.COLOR_BayerRGGB2GRAY,
    "bayer_bggr8": cv2.COLOR_BayerBGGR2GRAY,
    "bayer_gbrg8": cv2.COLOR_BayerGBRG2GRAY,
    "bayer_grbg8": cv2.COLOR_BayerGRBG2GRAY,
}
"""ROS names the Bayer pattern by its first row; OpenCV's constants name the same pattern by
its second (OpenCV's `BayerBG` is ROS's `rggb`): these pairs are cv_bridge's."""
_COLOR = {
    "rgb8": (3, cv2.COLOR_RGB2GRAY),
    "bgr8": (3, cv2.COLOR_BGR2GRAY),
    "rgba8": (4, cv2.COLOR_RGBA2GRAY),
    "bgra8": (4, cv2.COLOR_BGRA2GRAY),
}
ENCODINGS = ("mono8", "8UC1", "mono16", "16UC1", *_BAYER, *_COLOR)
"""The `sensor_msgs/Image` encodings accepted."""


class ImageError(ValueError):
    """A frame that cannot be read as it is described."""


def gray8_from_image(msg: Any, *, expected_size: tuple[int, int] | None = None) -> ImageU8:
    """8-bit grayscale (H, W) of a `sensor_msgs/Image`.

    mono16 / 16UC1 are scaled by 1/256 (the 16-bit range to 8 bits: a camera's 10 or
    12 bits are left-aligned by the driver, as `image_proc` expects).

    Args:
        msg: the message (fields height, width, encoding, is_bigendian, step, data).
        expected_size: (width, height) of the calibrated camera, or None.

    Raises:
        ImageError: an unsupported encoding, a step or data size that does not fit the
            encoding, or an image size that is not the camera's.
    """
    enc = str(msg.encoding)
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if enc not in ENCODINGS:
        raise ImageError(f"image encoding {enc!r} is not supported (one of {', '.join(ENCODINGS)})")
    if expected_size is not None and (w, h) != expected_size:
        raise ImageError(
            f"image is {w}x{h} but the camera is calibrated for "
            f"{expected_size[0]}x{expected_size[1]}"
        )
    if enc in ("mono16", "16UC1"):
        bpp = 2
    elif enc in _COLOR:
        bpp = _COLOR[enc][0]
    else:
        bpp = 1
    if step < w * bpp:
        raise ImageError(
            f"image step {step} is less than width {w} x {bpp} bytes a pixel of {enc!r}: "
            "the encoding does not match the data"
        )
    data = msg.data if isinstance(msg.data, bytes | bytearray) else bytes(msg.data)
    if len(data) != step * h:
        raise ImageError(
            f"image data holds {len(data)} bytes, step x height is {step * h} ({enc!r}, "
            f"{w}x{h}): the encoding does not match the data"
        )
    rows = np.frombuffer(data, dtype=np.uint8).reshape(h, step)[:, : w * bpp]
    if bpp == 2:
        dtype = ">u2" if msg.is_bigendian else "<u2"
        wide = np.ascontiguousarray(rows).view(dtype).reshape(h, w)
        return np.ascontiguousarray((wide.astype(np.uint16) >> 8).astype(np.uint8))
    if enc in _COLOR:
        channels, code = _COLOR[enc]
        return np.ascontiguousarray(cv2.cvtColor(rows.reshape(h, w, channels), code))
    if enc in _BAYER:
        return np.ascontiguousarray(cv2.cvtColor(np.ascontiguousarray(rows), _BAYER[enc]))
    return np.ascontiguousarray(rows)


def gray8_from_compressed(msg: Any, *, expected_size: tuple[int, int] | None = None) -> ImageU8:
    """8-bit grayscale (H, W) of a `sensor_msgs/CompressedImage` (PNG or JPEG, 8 or 16 bit).

    Raises:
        ImageError: a format other than PNG/JPEG, undecodable data, or a size that is not
            the camera's.
    """
    fmt = str(msg.format).lower()
    if "png" not in fmt and "jpeg" not in fmt and "jpg" not in fmt:
        raise ImageError(f"compressed image format {msg.format!r} is not PNG or JPEG")
    data = msg.data if isinstance(msg.data, bytes | bytearray) else bytes(msg.data)
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ImageError(f"compressed image ({msg.format!r}, {len(data)} bytes) does not decode")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if image.dtype == np.uint16:
        image = np.right_shift(image.astype(np.uint16), 8).astype(np.uint8)
    h, w = image.shape[:2]
    if expected_size is not None and (w, h) != expected_size:
        raise ImageError(
            f"image is {w}x{h} but the camera is calibrated for "
            f"{expected_size[0]}x{expected_size[1]}"
        )
    return np.ascontiguousarray(image, dtype=np.uint8)
