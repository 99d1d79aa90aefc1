"""Undo and redo of this user's own map edits, and whole-map import and clear (admin).

The buttons say what they would do ("Undo move of landmark 17"); a step that changes the
whole map (an import or clear, or undoing one) or leaves the site without landmarks opens a
dialog that names it and needs an explicit click. They are the API's actions
(`POST /map/undo`, `/map/redo`, `PUT /map`, `DELETE /map`) on the same data layer
(`store.history`), with the browser's user as the author.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import PurePath
from typing import TYPE_CHECKING, Literal

import viser

from store.errors import ConflictError
from store.history import MapStep
from store.landmarks import MapRepository, parse_map_csv, parse_map_json
from store.models import LandmarkCreate
from web.roles import Session
from web.status_line import StatusLine

if TYPE_CHECKING:  # viser 1.1 does not export the modal's handle type
    from viser._gui_handles import GuiModalHandle


def parse_map_file(name: str, content: bytes) -> list[LandmarkCreate]:
    """A map file (map.json or the CSV export) as landmarks; ValueError names the file."""
    try:
        text = content.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{name}: not UTF-8 text ({exc})") from None
    if PurePath(name).suffix.lower() == ".csv":
        return parse_map_csv(text, source=name)
    import json

    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{name}: not JSON ({exc}); a map is map.json or its CSV") from None
    return parse_map_json(data, source=name)


def button_label(step: MapStep | None, direction: Literal["undo", "redo"]) -> str:
    """ "Undo move of landmark 17", or "Nothing to undo"."""
    if step is None:
        return f"Nothing to {direction}"
    return step.title[0].upper() + step.title[1:]


class HistoryPanel:
    """Undo / Redo and the whole-map actions of one admin's browser."""

    def __init__(
        self,
        gui: viser.GuiApi,
        repo: MapRepository,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        self.gui, self.repo, self.session, self.notify = gui, repo, session, notify
        with gui.add_folder("Undo / redo (your edits)"):
            self.gui_undo = gui.add_button(
                "Nothing to undo", disabled=True, icon=viser.Icon.ARROW_BACK_UP
            )
            self.gui_redo = gui.add_button(
                "Nothing to redo", disabled=True, icon=viser.Icon.ARROW_FORWARD_UP
            )
            self.gui_status = gui.add_markdown("")
        self.status = StatusLine(self.gui_status)
        with gui.add_folder("Whole map", expand_by_default=False):
            self.gui_import = gui.add_upload_button(
                "Import map (map.json or CSV)", mime_type=".json,.csv,application/json,text/csv"
            )
            self.gui_clear = gui.add_button("Clear map", color="red")
        self.gui_undo.on_click(lambda _: self.request("undo"))
        self.gui_redo.on_click(lambda _: self.request("redo"))
        self.gui_import.on_upload(lambda _: self._on_upload())
        self.gui_clear.on_click(lambda _: self.request_clear())
        self.modal: GuiModalHandle | None = None
        self._pending: Callable[[], object] | None = None
        self._shown: tuple[str, bool, str, bool] | None = None
        self.refresh()

    # -- state ---------------------------------------------------------------------------------
    def refresh(self) -> None:
        """Relabel the buttons for this user's next undo and redo (call at a few hertz)."""
        actor = self.session.actor
        undo, redo = self.repo.history.next_undo(actor), self.repo.history.next_redo(actor)
        shown = (button_label(undo, "undo"), undo is None, button_label(redo, "redo"), redo is None)
        if shown != self._shown:
            self.gui_undo.label, self.gui_undo.disabled = shown[0], shown[1]
            self.gui_redo.label, self.gui_redo.disabled = shown[2], shown[3]
            self._shown = shown

    def _report(self, text: str, *, refused: bool = False) -> None:
        self.status.say(f"**refused**: {text}" if refused else text)
        if refused:
            self.notify("Refused", text)
        self.refresh()

    # -- undo / redo -----------------------------------------------------------------------
    def request(self, direction: Literal["undo", "redo"]) -> None:
        """The button: act at once, or ask first for a whole-map or emptying step."""
        h = self.repo.history
        step = (h.next_undo if direction == "undo" else h.next_redo)(self.session.actor)
        if step is None:
            self._report(f"nothing of yours to {direction}")
            return
        if step.needs_confirmation:
            after = "no landmarks" if step.landmarks_after == 0 else f"{step.landmarks_after}"
            self.ask(
                f"Confirm: {step.title}",
                f"This replaces the whole map: **{step.landmarks_now}** landmarks now, "
                f"**{after}** after it. Robots localize against the map.",
                "Yes, " + step.title,
                lambda: self.act(direction, confirm=True, expect=step.record_id),
            )
            return
        self.act(direction, confirm=False, expect=step.record_id)

    def act(
        self, direction: Literal["undo", "redo"], *, confirm: bool, expect: int | None
    ) -> MapStep | None:
        """Undo or redo through the data layer; returns the step taken (None if refused)."""
        h = self.repo.history
        try:
            step = (h.undo if direction == "undo" else h.redo)(
                self.session.actor, confirm=confirm, expect=expect
            )
        except (ConflictError, ValueError) as exc:
            self._report(str(exc), refused=True)
            return None
        self._report(f"done: {step.title} ({step.landmarks_after} landmarks in the map)")
        return step

    # -- whole map -----------------------------------------------------------------------------
    def _on_upload(self) -> None:
        up = self.gui_import.value
        self.request_import(up.name, up.content)

    def request_import(self, name: str, content: bytes) -> None:
        """Ask before replacing the map by a file's landmarks (refused files say why)."""
        try:
            items = parse_map_file(name, content)
        except ValueError as exc:
            self._report(str(exc), refused=True)
            return
        now = len(self.repo.list())
        self.ask(
            f"Confirm: replace the map by {name}",
            f"The map's **{now}** landmarks are replaced by the **{len(items)}** of `{name}` "
            "(one step of your undo).",
            "Yes, replace the map",
            lambda: self._replace(items, f"imported {len(items)} landmarks from {name}"),
        )

    def request_clear(self) -> None:
        now = len(self.repo.list())
        self.ask(
            "Confirm: clear the map",
            f"All **{now}** landmarks are removed: robots cannot localize until a map is "
            "imported again (one step of your undo).",
            "Yes, clear the map",
            lambda: self._replace([], f"cleared the map ({now} landmarks removed)"),
        )

    def _replace(self, items: list[LandmarkCreate], done: str) -> None:
        try:
            self.repo.replace_all(items, actor=self.session.actor, confirm=True)
        except (ConflictError, ValueError) as exc:
            self._report(str(exc), refused=True)
            return
        self._report(done)

    # -- the confirmation dialog -----------------------------------------------------------
    def ask(self, title: str, body: str, yes: str, action: Callable[[], object]) -> None:
        """A dialog naming the step: `yes` runs `action`, Cancel changes nothing."""
        self.close_dialog()
        with self.gui.add_modal(title) as modal:
            self.gui.add_markdown(body)
            gui_yes = self.gui.add_button(yes, color="red")
            gui_no = self.gui.add_button("Cancel")
        self.modal, self._pending = modal, action
        gui_yes.on_click(lambda _: self.confirm_dialog())
        gui_no.on_click(lambda _: self.cancel_dialog())

    def confirm_dialog(self) -> None:
        """The dialog's yes: take the step it named."""
        action = self._pending
        self.close_dialog()
        if action is not None:
            action()

    def cancel_dialog(self) -> None:
        self.close_dialog()
        self._report("cancelled: nothing changed")

    def close_dialog(self) -> None:
        if self.modal is not None:
            self.modal.close()
        self.modal = self._pending = None
