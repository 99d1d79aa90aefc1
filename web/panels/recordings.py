"""Recordings: start and stop a robot's recording, save its black box (its last seconds, as
`POST /api/v1/robots/{name}/black-box`), list the newest with a download link, and delete one
(admins, after ticking the confirmation). A thin client of the server's `Recordings` and its
catalog, as `/api/v1/robots/{name}/recording/*` and `/api/v1/recordings` are; the download
link is the viewer's own `/viewer/recordings/<name>.zip` (the browser's key is a cookie of
`/viewer`). Operators and admins.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import viser

from live.facades import Recordings
from store.errors import ConflictError, NotFoundError
from store.recording_catalog import RecordingInfo
from web.panels.monitor import local_time_text
from web.roles import Session


def recordings_text(found: Sequence[RecordingInfo], limit: int = 8) -> str:
    """Markdown: the newest `limit` recordings with their size, frames, why and a link."""
    if not found:
        return "_no recordings_"
    lines = []
    for r in found[:limit]:
        link = "(recording...)" if r.live else f"[download](/viewer/recordings/{r.name}.zip)"
        lines.append(
            f"- `{r.name}` {r.trigger}, {local_time_text(r.started)}, {r.frames} frames, "
            f"{r.size_bytes / 1e6:.1f} MB {link}"
        )
    if len(found) > limit:
        lines.append(f"- ... and {len(found) - limit} more (`GET /api/v1/recordings`)")
    return "\n".join(lines)


def _ignore(_: object) -> None:
    """A button callback returns nothing (the actions return what they did, for tests)."""


class RecordingsPanel:
    """One operator's (or admin's) recordings folder."""

    def __init__(
        self,
        gui: viser.GuiApi,
        recordings: Recordings,
        session: Session,
        robot: Callable[[], str],
        notify: Callable[[str, str], None],
    ) -> None:
        self.recordings, self.session, self.robot, self.notify = recordings, session, robot, notify
        with gui.add_folder("Recordings", expand_by_default=False):
            self.gui_start = gui.add_button("Start recording (robot above)")
            self.gui_stop = gui.add_button("Stop recording")
            self.gui_black_box = gui.add_button("Save black box (its last seconds)")
            self.gui_list = gui.add_markdown("")
            self.gui_name = self.gui_sure = self.gui_delete = None
            if session.can_commission:
                self.gui_name = gui.add_text("Recording to delete", "")
                self.gui_sure = gui.add_checkbox("Yes, delete it for good", False)
                self.gui_delete = gui.add_button("Delete recording", color="red")
                self.gui_delete.on_click(lambda _: _ignore(self.delete()))
        self.gui_start.on_click(lambda _: _ignore(self.start()))
        self.gui_stop.on_click(lambda _: _ignore(self.stop()))
        self.gui_black_box.on_click(lambda _: _ignore(self.save_black_box()))
        self._text = ""
        self._next = 0.0
        self.refresh()

    def refresh(self, *, every_s: float = 5.0) -> None:
        """List the recordings again, at most every `every_s` (it reads the folders)."""
        now = time.monotonic()
        if every_s > 0 and now < self._next:
            return
        self._next = now + every_s
        text = recordings_text(self.recordings.catalog.list())
        if text != self._text:
            self._text = self.gui_list.content = text

    def start(self) -> str | None:
        name = self.robot()
        try:
            path = self.recordings.start(name)
        except (KeyError, ValueError) as exc:  # NotFoundError is a KeyError
            self.notify("Recording refused", str(exc))
            return None
        self.notify("Recording", f"{name}: recording to {path.name}")
        self.refresh(every_s=0.0)
        return path.name

    def stop(self) -> str | None:
        name = self.robot()
        try:
            path = self.recordings.stop(name)
        except (KeyError, ValueError) as exc:
            self.notify("Recording refused", str(exc))
            return None
        self.notify(
            "Recording", f"{name}: " + ("not recording" if path is None else f"{path.name} saved")
        )
        self.refresh(every_s=0.0)
        return None if path is None else path.name

    def save_black_box(self) -> str | None:
        """Save the robot's black box now (trigger `operator`); the recording's name."""
        name = self.robot()
        try:
            saved = self.recordings.save_black_box(name)
        except (NotFoundError, ConflictError) as exc:
            self.notify("Black box not saved", str(exc))
            return None
        self.notify("Black box", f"{name}: saved as {saved.path.name} ({saved.bytes / 1e6:.1f} MB)")
        self.refresh(every_s=0.0)
        return saved.path.name

    def delete(self) -> bool:
        if self.gui_name is None or self.gui_sure is None:
            return False
        name = self.gui_name.value.strip()
        if not self.gui_sure.value:
            self.notify(
                "Delete recording", "tick 'Yes, delete it for good' first: it cannot be undone"
            )
            return False
        try:
            self.recordings.catalog.delete(name)
        except (NotFoundError, ConflictError) as exc:
            self.notify("Delete refused", str(exc))
            return False
        self.gui_sure.value = False  # type: ignore[misc]
        self.notify("Recording", f"{name} deleted")
        self.refresh(every_s=0.0)
        return True
