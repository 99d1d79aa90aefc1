"""The lens calibration panel: upload chessboard photos, calibrate, store with a robot.

The same calibration as `irloc calibrate` and `POST /robots/{name}/calibration/lens`
(`calibration.uploads.calibrate_from_uploads`); the robot's mounting (`T_BS`) is kept.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import viser

from calibration.board import parse_pattern
from calibration.lens import LensCalibration
from calibration.uploads import calibrate_from_uploads, mounting_kept
from web.roles import Session
from web.services import ViewerSite

MAX_PHOTOS = 60


class CalibrationPanel:
    """Per-browser lens calibration; photos stay in this browser's panel until stored."""

    def __init__(
        self,
        gui: viser.GuiApi,
        site: ViewerSite,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        self.site, self.session, self.notify = site, session, notify
        self.photos: list[tuple[str, bytes]] = []
        self.result: LensCalibration | None = None
        self.result_robot: str | None = None
        names = tuple(r.name for r in site.robots()) or ("(no robot)",)
        with gui.add_folder("Lens calibration", expand_by_default=False):
            self.gui_robot = gui.add_dropdown("Robot", names)
            self.gui_upload = gui.add_upload_button("Add photo", mime_type="image/*")
            self.gui_pattern = gui.add_text("Inner corners", "9x6")
            self.gui_square = gui.add_number("Square (m)", 0.025, min=0.001, max=1.0, step=0.001)
            self.gui_model = gui.add_dropdown("Lens model", ("pinhole", "fisheye"))
            self.gui_calibrate = gui.add_button("Calibrate lens")
            self.gui_store = gui.add_button("Store calibration", disabled=True)
            self.gui_clear = gui.add_button("Clear photos")
            self.gui_text = gui.add_markdown("No photos yet: add 15-25 that cover the edges.")
        self.gui_upload.on_upload(self._on_upload)
        self.gui_calibrate.on_click(self._on_calibrate)
        self.gui_store.on_click(lambda _e: self.store())
        self.gui_clear.on_click(lambda _e: self.clear())

    def _on_upload(self, event: viser.GuiEvent[viser.GuiUploadButtonHandle]) -> None:
        upload = event.target.value
        self.add_photo(upload.name, upload.content)

    def _on_calibrate(self, _event: object) -> None:
        self.calibrate()

    def add_photo(self, name: str, content: bytes) -> None:
        """Keep one uploaded photo (at most MAX_PHOTOS)."""
        if len(self.photos) >= MAX_PHOTOS:
            self.notify("Lens calibration", f"at most {MAX_PHOTOS} photos")
            return
        self.photos.append((name, content))
        self.result = None
        self.gui_store.disabled = True
        self.gui_text.content = (
            f"{len(self.photos)} photo(s): {', '.join(n for n, _ in self.photos[-5:])}"
        )

    def clear(self) -> None:
        self.photos.clear()
        self.result = None
        self.gui_store.disabled = True
        self.gui_text.content = "No photos yet."

    def calibrate(self) -> str:
        """Calibrate from the photos, keeping the robot's mounting; returns the summary shown.
        Bad photos, too few views or a wrong pattern show the reason and keep nothing."""
        robot = next((r for r in self.site.robots() if r.name == self.gui_robot.value), None)
        try:
            options: dict[str, Any] = {
                "pattern": parse_pattern(self.gui_pattern.value),
                "square_m": float(self.gui_square.value),
                "model": self.gui_model.value,
                **mounting_kept(None if robot is None else robot.camera),
            }
            result = calibrate_from_uploads(list(self.photos), **options)
        except ValueError as exc:
            self.result = None
            self.gui_store.disabled = True
            self.gui_text.content = f"**Not calibrated:** {exc}"
            return self.gui_text.content
        self.result, self.result_robot = result, None if robot is None else robot.name
        self.gui_store.disabled = robot is None or not self.session.can_commission
        self.gui_text.content = "```\n" + result.summary() + "\n```"
        return self.gui_text.content

    def store(self) -> None:
        """Store the last calibration with its robot (admins and operators only)."""
        if self.result is None or self.result_robot is None:
            return
        if not self.session.can_commission:
            self.notify("Lens calibration", "your key may not change robots")
            return
        self.site.store_camera(self.result_robot, self.result.camera, actor=self.session.actor)
        self.gui_store.disabled = True
        self.notify("Lens calibration", f"stored with robot {self.result_robot}")
