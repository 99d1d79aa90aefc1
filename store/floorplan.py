"""The site's floor plan: one PNG or JPEG image placed on the floor by two points.

Two points known both in the image (pixels: column right, row down) and on the floor
(world metres, REP-103: x east, y north, seen from above) fix a similarity: a scale, a
rotation about z and a shift (the image is not mirrored: its rows run toward -y when the
rotation is 0). The image and its placement live in the data folder (`floorplan.png` or
`.jpg`, `floorplan.json`), each written to a temporary file and renamed, so a crash never
leaves half a plan.
"""

from __future__ import annotations

import json
import math
import os
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from store.errors import NotFoundError

MAX_BYTES = 25 * 1024 * 1024
MAX_SIDE_PX = 12_000
MediaType = Literal["image/png", "image/jpeg"]
_SUFFIX: dict[str, str] = {"image/png": ".png", "image/jpeg": ".jpg"}


@dataclass(frozen=True)
class Placement:
    """Two points of the image and where they lie on the floor.

    Attributes:
        a_px, b_px: (column, row) of two image points, pixels.
        a_m, b_m: their (x, y) on the floor in the world frame, metres.
    """

    a_px: tuple[float, float]
    a_m: tuple[float, float]
    b_px: tuple[float, float]
    b_m: tuple[float, float]

    def check(self) -> None:
        """ValueError naming what is wrong (coincident or non-finite points)."""
        for name in ("a_px", "a_m", "b_px", "b_m"):
            v = getattr(self, name)
            if len(v) != 2 or not all(math.isfinite(float(c)) for c in v):
                raise ValueError(f"floor plan placement: {name} must be two finite numbers")
        if math.dist(self.a_px, self.b_px) < 1.0:
            raise ValueError("floor plan placement: a_px and b_px are less than 1 px apart")
        if math.dist(self.a_m, self.b_m) < 1e-3:
            raise ValueError("floor plan placement: a_m and b_m are less than 1 mm apart")

    def similarity(self) -> tuple[float, float, np.ndarray]:
        """(metres per pixel, rotation about z in radians, shift (2,) metres): the floor point
        of pixel (u, v) is `scale * R(rotation) @ (u, -v) + shift`."""
        qa = np.array([self.a_px[0], -self.a_px[1]], dtype=np.float64)
        qb = np.array([self.b_px[0], -self.b_px[1]], dtype=np.float64)
        pa, pb = np.array(self.a_m, dtype=np.float64), np.array(self.b_m, dtype=np.float64)
        dq, dp = qb - qa, pb - pa
        scale = float(np.linalg.norm(dp) / np.linalg.norm(dq))
        rot = math.atan2(dp[1], dp[0]) - math.atan2(dq[1], dq[0])
        rot = math.atan2(math.sin(rot), math.cos(rot))
        c, s = math.cos(rot), math.sin(rot)
        shift = pa - scale * np.array([[c, -s], [s, c]]) @ qa
        return scale, rot, shift

    def floor_from_pixel(self, u: float, v: float) -> tuple[float, float]:
        """Where an image pixel lies on the floor (world x, y, metres)."""
        scale, rot, shift = self.similarity()
        c, s = math.cos(rot), math.sin(rot)
        p = scale * np.array([[c, -s], [s, c]]) @ np.array([u, -v]) + shift
        return float(p[0]), float(p[1])


@dataclass(frozen=True)
class FloorPlanInfo:
    """The stored plan: its image size, placement and what follows from it.

    Attributes:
        width_px, height_px: image size.
        media_type: image/png or image/jpeg.
        placement: the two points.
        metres_per_px: scale; rotation_rad: about z (REP-103, CCW from +x).
        center_m: the image centre on the floor; width_m, height_m: its size there.
    """

    width_px: int
    height_px: int
    media_type: str
    placement: Placement
    metres_per_px: float
    rotation_rad: float
    center_m: tuple[float, float]
    width_m: float
    height_m: float


def image_size(content: bytes, media_type: str) -> tuple[int, int]:
    """(width, height) of a PNG or JPEG; ValueError saying what is wrong with the file."""
    if media_type not in _SUFFIX:
        raise ValueError(f"floor plan: {media_type or 'no type'} is not image/png or image/jpeg")
    if len(content) > MAX_BYTES:
        raise ValueError(f"floor plan: {len(content)} bytes, more than {MAX_BYTES}")
    magic = content[:8]
    is_png, is_jpeg = magic.startswith(b"\x89PNG\r\n\x1a\n"), magic.startswith(b"\xff\xd8\xff")
    if not (is_png or is_jpeg) or (media_type == "image/png") != is_png:
        raise ValueError(f"floor plan: the data is not a {media_type} image")
    img = cv2.imdecode(np.frombuffer(content, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"floor plan: the {media_type} image cannot be decoded")
    h, w = img.shape[:2]
    if max(h, w) > MAX_SIDE_PX:
        raise ValueError(f"floor plan: {w}x{h} px, more than {MAX_SIDE_PX} px a side")
    return int(w), int(h)


def _info(w: int, h: int, media_type: str, placement: Placement) -> FloorPlanInfo:
    scale, rot, _ = placement.similarity()
    cx, cy = placement.floor_from_pixel(w / 2.0, h / 2.0)
    return FloorPlanInfo(w, h, media_type, placement, scale, rot, (cx, cy), scale * w, scale * h)


def _write(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


class FloorPlanStore:
    """The floor plan in a data folder; `version` grows with every change (the viewer
    redraws when it changes).

    Args:
        folder: the site's data folder.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self._lock = threading.Lock()
        self.version = 0

    @property
    def _meta(self) -> Path:
        return self.folder / "floorplan.json"

    def info(self) -> FloorPlanInfo | None:
        """The stored plan's description, None when there is none."""
        try:
            meta = json.loads(self._meta.read_text())
        except FileNotFoundError:
            return None
        p = meta["placement"]
        placement = Placement(
            tuple(p["a_px"]),
            tuple(p["a_m"]),
            tuple(p["b_px"]),
            tuple(p["b_m"]),
        )
        return _info(int(meta["width_px"]), int(meta["height_px"]), meta["media_type"], placement)

    def image(self) -> tuple[bytes, str] | None:
        """(the image file's bytes, its media type), None when there is no plan."""
        info = self.info()
        if info is None:
            return None
        path = self.folder / ("floorplan" + _SUFFIX[info.media_type])
        try:
            return path.read_bytes(), info.media_type
        except FileNotFoundError:
            return None

    def put(self, content: bytes, media_type: str, placement: Placement) -> FloorPlanInfo:
        """Store a new plan (replacing any); ValueError for a bad image or placement."""
        placement.check()
        w, h = image_size(content, media_type)
        with self._lock:
            self.folder.mkdir(parents=True, exist_ok=True)
            for suffix in set(_SUFFIX.values()) - {_SUFFIX[media_type]}:
                (self.folder / ("floorplan" + suffix)).unlink(missing_ok=True)
            _write(self.folder / ("floorplan" + _SUFFIX[media_type]), content)
            self._save_meta(w, h, media_type, placement)
        return _info(w, h, media_type, placement)

    def place(self, placement: Placement) -> FloorPlanInfo:
        """Move the stored plan; NotFoundError when there is none."""
        placement.check()
        with self._lock:
            info = self.info()
            if info is None:
                raise NotFoundError("there is no floor plan: upload one first")
            self._save_meta(info.width_px, info.height_px, info.media_type, placement)
        return _info(info.width_px, info.height_px, info.media_type, placement)

    def delete(self) -> bool:
        """Remove the plan; False when there was none."""
        with self._lock:
            existed = self._meta.exists()
            self._meta.unlink(missing_ok=True)
            for suffix in _SUFFIX.values():
                (self.folder / ("floorplan" + suffix)).unlink(missing_ok=True)
            self.version += 1
        return existed

    def _save_meta(self, w: int, h: int, media_type: str, placement: Placement) -> None:
        meta = {"width_px": w, "height_px": h, "media_type": media_type}
        meta["placement"] = {k: list(v) for k, v in asdict(placement).items()}
        _write(self._meta, json.dumps(meta, indent=1).encode())
        self.version += 1
