"""The floor selector: which floor's plan, ceiling, landmarks and robots the scene shows,
and where the robots on the other floors are.

The scene is shared by every browser, so the floor shown is the site viewer's (a choice in
one browser shows in all). Commissioning, survey and coverage act on what is shown: the
coverage map and the landmark tables list the shown floor's landmarks. The same choice
through the API: `GET /api/v1/floors`, `GET /api/v1/landmarks?floor=ID`.
"""

from __future__ import annotations

import viser

from web.services import ViewerSite

ALL = "every floor"


class FloorPanel:
    """A dropdown of the floors and a line naming the robots elsewhere."""

    def __init__(self, gui: viser.GuiApi, site: ViewerSite) -> None:
        self.site = site
        floors = site.floors()
        self._ids = {f"{name} ({fid})": fid for fid, name in floors}
        with gui.add_folder("Floor"):
            self.gui_floor = gui.add_dropdown("Show", (ALL, *self._ids))
            self.gui_elsewhere = gui.add_markdown("")
        self.gui_floor.on_update(lambda _e: self._choose())

    def _choose(self) -> None:
        self.site.show_floor(self._ids.get(str(self.gui_floor.value)))
        self.refresh()

    def refresh(self) -> None:
        """The robots not on the floor shown, with theirs."""
        away = self.site.elsewhere()
        self.gui_elsewhere.content = (
            "On other floors: " + ", ".join(f"{r} (floor {f})" for r, f in away) if away else ""
        )
