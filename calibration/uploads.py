"""Lens calibration from uploaded or on-disk photos: decoding, then `calibrate_lens`.

The server's upload route and `irloc calibrate` both come through here, so a photo that
cannot be decoded is reported the same way (by its name) everywhere. Each file's size is read
from its header (Pillow, which decodes nothing to do so) before OpenCV decodes it: a small
file that claims a huge image (a decompression bomb) is refused in microseconds, by name.
"""

from __future__ import annotations

import io
import re
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from PIL import Image, UnidentifiedImageError

from calibration.lens import LensCalibration, calibrate_lens
from localizer.camera import CameraModel

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
MAX_IMAGE_PIXELS = 40_000_000
"""Largest photo decoded, pixels (a 40 MP camera; the board needs far fewer)."""
MAX_TOTAL_PIXELS = 400_000_000
"""Largest sum over the photos of one calibration, pixels (bounds the memory held)."""


def image_pixels(data: bytes) -> tuple[int, str] | None:
    """(pixel count, "W x H px") from an encoded image's header without decoding its
    pixels; None when Pillow does not recognise the header (OpenCV may still read it)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as img:
                width, height = img.size
    except Image.DecompressionBombError as exc:  # past Pillow's own limit: no size given
        found = re.search(r"\((\d+) pixels\)", str(exc))
        n = int(found.group(1)) if found else 2**62
        return n, f"{n / 1e6:g} MP"
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
        return None
    return int(width) * int(height), f"{width} x {height} px"


def decode_image(
    name: str, data: bytes, *, max_pixels: int = MAX_IMAGE_PIXELS
) -> npt.NDArray[np.generic] | None:
    """Decode one encoded image (PNG, JPEG, ... as `cv2.imdecode`), refusing from its header
    an image of more than `max_pixels`; None when it cannot be decoded.

    Raises:
        ValueError: naming the file and its size when it is too large.
    """
    if not data:
        return None
    size = image_pixels(data)
    if size is not None and size[0] > max_pixels:
        raise ValueError(
            f"{name}: {size[1]} is more than {max_pixels / 1e6:.3g} MP, the largest image decoded"
        )
    img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if img is not None and img.shape[0] * img.shape[1] > max_pixels:
        raise ValueError(
            f"{name}: {img.shape[1]} x {img.shape[0]} px is more than {max_pixels / 1e6:.3g} MP"
        )
    return img


def decode_images(files: Sequence[tuple[str, bytes]]) -> list[npt.NDArray[np.generic]]:
    """Decode image files held in memory.

    Args:
        files: (name, encoded bytes) pairs (PNG, JPEG, ... anything `cv2.imdecode` reads).

    Returns:
        The decoded images, gray or BGR, in input order.

    Raises:
        ValueError: naming every file that is empty or cannot be decoded, or the first that
            is larger than `MAX_IMAGE_PIXELS` (or would take the total past
            `MAX_TOTAL_PIXELS`), from its header, before anything is decoded.
    """
    total = 0
    for name, data in files:
        size = image_pixels(data)
        if size is None:
            continue
        if size[0] > MAX_IMAGE_PIXELS:
            decode_image(name, data)  # raises, naming the size
        total += size[0]
        if total > MAX_TOTAL_PIXELS:
            raise ValueError(
                f"{name}: the photos up to this one hold {total / 1e6:.0f} MP, more than "
                f"{MAX_TOTAL_PIXELS / 1e6:g} MP: send fewer or smaller photos"
            )
    images: list[npt.NDArray[np.generic]] = []
    bad: list[str] = []
    for name, data in files:
        img = decode_image(name, data)
        if img is None:
            bad.append(name)
        else:
            images.append(img)
    if bad:
        raise ValueError(
            f"{len(bad)} file{'s' if len(bad) > 1 else ''} could not be decoded as an image: "
            + ", ".join(bad)
        )
    return images


def calibrate_from_uploads(files: list[tuple[str, bytes]], **options: Any) -> LensCalibration:
    """Calibrate the lens from uploaded photos.

    Args:
        files: (file name, encoded bytes) pairs, e.g. the parts of a multipart upload.
        **options: keyword arguments of `calibrate_lens` (pattern, square_m, model, board,
            expected_resolution, T_body_camera, rate_hz, config, progress).

    Raises:
        ValueError: undecodable files (named), and everything `calibrate_lens` rejects.
    """
    if not files:
        raise ValueError("no files uploaded")
    images = decode_images(files)
    return calibrate_lens(images, names=[name for name, _ in files], **options)


def mounting_kept(camera: CameraModel | None) -> dict[str, Any]:
    """`calibrate_lens` options that keep a camera's mounting (`T_BS`) and frame rate, so a
    new lens calibration replaces only the intrinsics; none for a robot without a camera."""
    if camera is None:
        return {}
    return {"T_body_camera": np.array(camera.T_body_camera), "rate_hz": camera.rate_hz}


def image_paths(paths: Sequence[str | Path]) -> list[Path]:
    """Expand folders into their image files (sorted); check that every file exists.

    Raises:
        ValueError: naming a missing path or a folder without images.
    """
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)
            if not found:
                raise ValueError(f"{p}: folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise ValueError(f"{p}: no such file or folder")
    return out
