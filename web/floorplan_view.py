"""The floor plan in the viewer: the image on the floor (`/floorplan`, shared by every
browser) and the admin's controls to upload and place it by two points.

Both go through `store.floorplan.FloorPlanStore`, as `PUT /map/floorplan` does; the layer
redraws when the store's `version` changes (an upload through the API shows within a
landmark refresh, 0.5 s).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import PurePath

import cv2
import numpy as np
import viser

from store.floorplan import FloorPlanInfo, FloorPlanStore, Placement, image_size
from web.footprint import Bounds
from web.status_line import StatusLine

FLOORPLAN_Z_M = -0.01
"""The image lies just below the floor grid (its lines stay visible on it), metres."""
MAX_TEXTURE_PX = 2048
"""Larger plans are scaled down for the browser (the stored file is kept as uploaded)."""


def floorplan_pixels(content: bytes, *, max_px: int = MAX_TEXTURE_PX) -> np.ndarray:
    """The image as viser's `add_image` wants it for a north-up plan: RGB (H, W, 3)
    uint8, bottom row first, at most `max_px` a side."""
    img = cv2.imdecode(np.frombuffer(content, dtype=np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError("floor plan: the stored image cannot be decoded")
    h, w = img.shape[:2]
    if max(h, w) > max_px:
        f = max_px / max(h, w)
        img = cv2.resize(
            img, (max(1, round(w * f)), max(1, round(h * f))), interpolation=cv2.INTER_AREA
        )
    # BGR -> RGB; rows reversed: viser's image plane puts the array's first row at -y
    return np.ascontiguousarray(img[::-1, :, ::-1])


def wxyz_about_z(angle: float) -> tuple[float, float, float, float]:
    return (math.cos(angle / 2.0), 0.0, 0.0, math.sin(angle / 2.0))


class FloorPlanLayer:
    """The `/floorplan` image node of the shared scene."""

    def __init__(self, scene: viser.SceneApi, store: FloorPlanStore) -> None:
        self.scene, self.store = scene, store
        self._version: int | None = None
        self.info: FloorPlanInfo | None = None
        """What is drawn (None: no plan)."""

    def follow(self, store: FloorPlanStore) -> bool:
        """Show `store`'s plan from now on (another floor's); True when it is another
        store (then redrawn at once)."""
        if store is self.store:
            return False
        self.store, self._version = store, None
        self.refresh()
        return True

    def refresh(self) -> bool:
        """Redraw when the plan changed; True when it did."""
        if self._version == self.store.version:
            return False
        self._version = self.store.version
        found, info = self.store.image(), self.store.info()
        if found is None or info is None:
            self.scene.remove_by_name("/floorplan")
            self.info = None
            return True
        self.scene.add_image(
            "/floorplan",
            floorplan_pixels(found[0]),
            info.width_m,
            info.height_m,
            format="jpeg",
            jpeg_quality=90,
            cast_shadow=False,
            receive_shadow=False,
            position=(info.center_m[0], info.center_m[1], FLOORPLAN_Z_M),
            wxyz=wxyz_about_z(info.rotation_rad),
        )
        self.info = info
        return True


def stretched_placement(bounds: Bounds, width_px: int) -> Placement:
    """The image's top edge along the site's north edge, its width the site's width."""
    x0, x1, _, y1 = bounds
    return Placement((0.0, 0.0), (x0, y1), (float(width_px), 0.0), (x1, y1))


class FloorPlanPanel:
    """Upload, place (two points) and remove the floor plan (admin); `store` may be a
    function giving the store of the floor shown (each floor has its plan)."""

    def __init__(
        self,
        gui: viser.GuiApi,
        store: FloorPlanStore | Callable[[], FloorPlanStore],
        bounds: Bounds,
        notify: Callable[[str, str], None],
    ) -> None:
        self._store_of = store if callable(store) else lambda: store
        self.bounds, self.notify = bounds, notify
        x0, x1, _, y1 = bounds
        with gui.add_folder("Floor plan", expand_by_default=False):
            gui.add_markdown(
                "PNG or JPEG. Two points known in the image (column, row in pixels) and "
                "on the floor (x, y in metres) place it; *stretch* lays its top edge along "
                "the site's north edge instead."
            )
            self.gui_stretch = gui.add_checkbox("Stretch across the site", True)
            self.gui_a_px = gui.add_vector2("A in image (px)", (0.0, 0.0), step=1.0)
            self.gui_a_m = gui.add_vector2("A on floor (m)", (x0, y1), step=0.01)
            self.gui_b_px = gui.add_vector2("B in image (px)", (1000.0, 0.0), step=1.0)
            self.gui_b_m = gui.add_vector2("B on floor (m)", (x1, y1), step=0.01)
            self.gui_upload = gui.add_upload_button(
                "Upload floor plan", mime_type="image/png,image/jpeg"
            )
            self.gui_place = gui.add_button("Place by the two points")
            self.gui_remove = gui.add_button("Remove floor plan")
            self.gui_status = gui.add_markdown("")
        self.status = StatusLine(self.gui_status)
        self.gui_upload.on_upload(lambda _: self._on_upload())
        self.gui_place.on_click(lambda _: self._on_place())
        self.gui_remove.on_click(lambda _: self.remove())

    @property
    def store(self) -> FloorPlanStore:
        """The store the panel acts on (the floor shown's)."""
        return self._store_of()

    def _points(self) -> Placement:
        a_px, a_m = self.gui_a_px.value, self.gui_a_m.value
        b_px, b_m = self.gui_b_px.value, self.gui_b_m.value
        return Placement((a_px[0], a_px[1]), (a_m[0], a_m[1]), (b_px[0], b_px[1]), (b_m[0], b_m[1]))

    def _on_upload(self) -> None:
        up = self.gui_upload.value
        self.upload(up.name, up.content)

    def upload(self, name: str, content: bytes) -> FloorPlanInfo | None:
        """Store a plan file (media type from its name), placed as the panel says."""
        suffix = PurePath(name).suffix.lower()
        media = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}.get(suffix)
        try:
            if media is None:
                raise ValueError(f"{name}: a floor plan is a .png, .jpg or .jpeg file")
            if self.gui_stretch.value:
                placement = stretched_placement(self.bounds, image_size(content, media)[0])
            else:
                placement = self._points()
            info = self.store.put(content, media, placement)
        except ValueError as exc:
            self._refused(str(exc))
            return None
        return self._done(f"{name}", info)

    def _on_place(self) -> None:
        self.place()

    def place(self) -> FloorPlanInfo | None:
        try:
            info = self.store.place(self._points())
        except (KeyError, ValueError) as exc:
            self._refused(str(exc))
            return None
        return self._done("placed", info)

    def remove(self) -> None:
        self.status.say("removed" if self.store.delete() else "there was no plan")

    def _done(self, what: str, info: FloorPlanInfo) -> FloorPlanInfo:
        self.status.say(
            f"{what}: {info.width_px}x{info.height_px} px, {100 * info.metres_per_px:.2f} cm "
            f"a pixel, {info.width_m:.1f} x {info.height_m:.1f} m, turned "
            f"{math.degrees(info.rotation_rad):.1f} deg"
        )
        return info

    def _refused(self, text: str) -> None:
        self.status.say(f"**refused**: {text}")
        self.notify("Floor plan", text)
