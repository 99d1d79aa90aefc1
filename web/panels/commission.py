"""Commissioning: add, move and delete landmarks, edit height, lock surveyed ones.

Positions come from the number fields or from a click on the ceiling (the click ray meets
the ceiling plane; a click within `pick_radius_m` of a landmark selects it). Every change
goes through the site's data layer (audited, actor = this browser's user; undo and redo:
`web.panels.history`). Admin only.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import viser

from web.geometry import ray_plane_point
from web.roles import Session
from web.services import LandmarkState, ViewerSite
from web.status_line import StatusLine


def nearest_landmark(
    landmarks: list[LandmarkState], point: np.ndarray, radius_m: float
) -> LandmarkState | None:
    """The landmark closest to `point` (horizontally), if within `radius_m`."""
    best, best_d = None, radius_m
    for lm in landmarks:
        d = math.hypot(lm.x - point[0], lm.y - point[1])
        if d <= best_d:
            best, best_d = lm, d
    return best


class CommissionPanel:
    """The map editing controls of one admin's browser."""

    def __init__(
        self,
        client: viser.ClientHandle,
        site: ViewerSite,
        session: Session,
        notify: Callable[[str, str], None],
        *,
        pick_radius_m: float = 0.25,
    ) -> None:
        self.client, self.site, self.session, self.notify = client, site, session, notify
        self.pick_radius_m = pick_radius_m
        gui = client.gui
        h = site.ceiling_height()
        with gui.add_folder("Landmark"):
            self.gui_id = gui.add_number("ID", 1, min=0, step=1)
            self.gui_x = gui.add_number("x (m)", 0.0, step=0.01)
            self.gui_y = gui.add_number("y (m)", 0.0, step=0.01)
            self.gui_z = gui.add_number("height (m)", round(h, 3), min=0.0, step=0.01)
            self.gui_radio = gui.add_text(
                "Radio address",
                "",
                hint="16 hex digits, e.g. 0013A20041B2C3D4: without it the landmark cannot "
                "be switched, identified by blinking or surveyed",
            )
            self.gui_pick = gui.add_checkbox("Pick on ceiling", False)
            self.gui_add = gui.add_button("Add landmark")
            self.gui_move = gui.add_button("Move / set height")
            self.gui_lock = gui.add_button("Lock (surveyed)")
            self.gui_unlock = gui.add_button("Unlock")
            self.gui_delete = gui.add_button("Delete landmark", color="red")
            self.gui_status = gui.add_markdown("")
        self.status = StatusLine(self.gui_status)
        self.gui_add.on_click(lambda _: self._do(self.add))
        self.gui_move.on_click(lambda _: self._do(self.move))
        self.gui_lock.on_click(lambda _: self._do(lambda: self.set_locked(True)))
        self.gui_unlock.on_click(lambda _: self._do(lambda: self.set_locked(False)))
        self.gui_delete.on_click(lambda _: self._do(self.delete))
        self.gui_pick.on_update(lambda _: self._pick_mode(self.gui_pick.value))

    # -- actions (return a status line; ValueError/KeyError become a notification) --------
    def _do(self, action: Callable[[], str]) -> None:
        try:
            text = action()
        except (KeyError, ValueError) as exc:
            self.status.say(f"**refused**: {exc}")
            self.notify("Refused", str(exc))
            return
        self.status.say(text)

    def _landmark(self) -> LandmarkState:
        lid = int(self.gui_id.value)
        for lm in self.site.landmarks():
            if lm.id == lid:
                return lm
        raise KeyError(f"no landmark {lid}")

    def add(self) -> str:
        lid = int(self.gui_id.value)
        x, y, z = float(self.gui_x.value), float(self.gui_y.value), float(self.gui_z.value)
        radio = self.gui_radio.value.strip() or None
        self.site.add_landmark(lid, x, y, z, actor=self.session.actor, radio=radio)
        text = f"added landmark {lid} at ({x:.2f}, {y:.2f}, {z:.2f}) m"
        if radio is None:
            text += " without a radio: it cannot be switched, identified by blinking or surveyed"
        else:
            text += f", radio {radio}"
        return text

    def move(self) -> str:
        lm = self._landmark()
        if lm.locked:
            raise ValueError(f"landmark {lm.id} is locked (surveyed): unlock it first")
        x, y, z = float(self.gui_x.value), float(self.gui_y.value), float(self.gui_z.value)
        self.site.update_landmark(lm.id, actor=self.session.actor, x=x, y=y, z=z)
        return f"moved landmark {lm.id} to ({x:.2f}, {y:.2f}, {z:.2f}) m"

    def set_locked(self, locked: bool) -> str:
        lm = self._landmark()
        self.site.update_landmark(lm.id, actor=self.session.actor, locked=locked)
        return f"landmark {lm.id} {'locked' if locked else 'unlocked'}"

    def delete(self) -> str:
        lm = self._landmark()
        if lm.locked:
            raise ValueError(f"landmark {lm.id} is locked (surveyed): unlock it first")
        self.site.delete_landmark(lm.id, actor=self.session.actor)
        return f"deleted landmark {lm.id}"

    # -- picking on the ceiling ---------------------------------------------------------------
    def _pick_mode(self, on: bool) -> None:
        scene = self.client.scene
        if on:
            scene.on_click()(self.on_scene_click)
        else:
            scene.remove_click_callback(self.on_scene_click)

    def on_scene_click(self, event: viser.SceneClickEvent) -> None:
        """Select the landmark clicked, or put the ceiling point into the fields."""
        self.pick(event.ray_origin, event.ray_direction)

    def pick(
        self, origin: tuple[float, float, float], direction: tuple[float, float, float]
    ) -> None:
        p = ray_plane_point(origin, direction, float(self.gui_z.value))
        if p is None:
            self.status.say("that click does not reach the ceiling")
            return
        lm = nearest_landmark(self.site.landmarks(), p, self.pick_radius_m)
        if lm is not None:
            self.gui_id.value = lm.id  # type: ignore[misc]
            self.gui_x.value, self.gui_y.value, self.gui_z.value = lm.x, lm.y, lm.z  # type: ignore[misc]
            self.gui_radio.value = lm.radio or ""  # type: ignore[misc]
            self.status.say(f"selected landmark {lm.id}")
        else:
            self.gui_x.value = round(float(p[0]), 3)  # type: ignore[misc]
            self.gui_y.value = round(float(p[1]), 3)  # type: ignore[misc]
            self.status.say(f"ceiling point ({p[0]:.2f}, {p[1]:.2f}) m")
