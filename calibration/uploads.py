"""Lens calibration from uploaded or on-disk photos: decoding, then `calibrate_lens`.

The server's upload route and `irloc calibrate` both come through here, so a photo that
cannot be decoded is reported the same way (by its name) everywhere.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from calibration.lens import LensCalibration, calibrate_lens
from localizer.camera import CameraModel

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")


def decode_images(files: Sequence[tuple[str, bytes]]) -> list[npt.NDArray[np.generic]]:
    """Decode image files held in memory.

    Args:
        files: (name, encoded bytes) pairs (PNG, JPEG, ... anything `cv2.imdecode` reads).

    Returns:
        The decoded images, gray or BGR, in input order.

    Raises:
        ValueError: naming every file that is empty or cannot be decoded.
    """
    images: list[npt.NDArray[np.generic]] = []
    bad: list[str] = []
    for name, data in files:
        img = None
        if data:
            img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
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
