"""`ClientPanels`: one browser's GUI, built for its role, and its refresh.

Everyone: the selected landmark or robot (click-to-inspect), robots, uncertainty, events,
batteries, zones, coverage and history playback. Operators also: relocalize, recordings,
cells replaced. Admins also: the Commission tab (wizard, landmarks, map history, proposals,
calibration, floor plan), the Survey tab, and editing zones.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from typing import TYPE_CHECKING

import viser

from store.floorplan import FloorPlanStore
from web.floorplan_view import FloorPlanPanel
from web.layout import ClientLayout, wait_for_width, window_class
from web.panels.calibration import CalibrationPanel
from web.panels.commission import CommissionPanel
from web.panels.coverage import CoveragePanel
from web.panels.floor import FloorPanel
from web.panels.history import HistoryPanel
from web.panels.inspect import InspectPanel
from web.panels.monitor import MonitorPanel
from web.panels.playback import PlaybackPanel
from web.panels.proposals import ProposalsPanel
from web.panels.recordings import RecordingsPanel
from web.panels.survey import SurveyPanel
from web.panels.view import ViewPanel
from web.panels.wizard import WizardPanel
from web.panels.zones import ZonesPanel
from web.roles import Session
from web.services import EventLine, LandmarkState, RobotState

if TYPE_CHECKING:
    from web.viewer import Viewer


class ClientPanels:
    """The panels of one browser (built on connect, refreshed by the viewer's loop)."""

    def __init__(self, viewer: Viewer, client: viser.ClientHandle, session: Session) -> None:

        def notify(title: str, body: str) -> None:
            client.add_notification(title, body, auto_close_seconds=6.0)

        gui = client.gui
        self.layout = ClientLayout(client)  # a wide screen gets a wider panel
        gui.add_markdown(f"**irloc** - signed in as *{session.role}*")
        # on a phone every panel starts folded into one line: unfolded, the panel covered
        # the hall (the browser's size arrives with its first camera message)
        width = wait_for_width(client, timeout_s=2.0)
        kind = window_class(width)
        with (
            gui.add_folder("Panels", expand_by_default=False) if kind == "phone" else nullcontext()
        ):
            self._build(viewer, client, session, notify)
        # the top view fitted to this window, beside (or above) the panel; a browser whose
        # size came later than the wait (a loaded machine) is fitted when it comes
        self._fitted = False
        self._fit_lock = threading.Lock()
        client.camera.on_update(self._fit_view_once)
        if wait_for_width(client, timeout_s=0.0) > 0:
            self._fit_view_once(client.camera)

    def _fit_view_once(self, camera: viser.CameraHandle) -> None:
        """Fit the top view to the window the first time its size is known."""
        width = int(camera.image_width)
        if width <= 0:
            return
        with self._fit_lock:
            if self._fitted:
                return
            self._fitted = True
        kind = window_class(width)
        panel_px = {"phone": 0.0, "wide": self.layout.config.wide_panel_px}.get(kind, 320.0)
        self.view.fit_window(width, camera.image_height, panel_px)

    def _build(
        self,
        viewer: Viewer,
        client: viser.ClientHandle,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        site, gui = viewer.site, client.gui
        assert viewer.scene is not None  # started
        bounds, ceiling_z = viewer.scene.bounds, viewer.scene.ceiling_z
        self.view = ViewPanel(client, bounds, ceiling_z, [r.name for r in site.robots()])
        self.floor = FloorPanel(gui, site) if len(site.floors()) > 1 else None
        self.inspect = InspectPanel(gui, site, session, viewer.last_use, notify)
        self.monitor: MonitorPanel
        self.wizard: WizardPanel | None = None
        self.survey: SurveyPanel | None = None
        self.commission: CommissionPanel | None = None
        self.history: HistoryPanel | None = None
        self.proposals: ProposalsPanel | None = None
        self.recordings: RecordingsPanel | None = None
        self.zones: ZonesPanel | None = None
        self.playback: PlaybackPanel | None = None
        self.floorplan: FloorPlanPanel | None = None
        if session.can_commission:
            tabs = gui.add_tab_group()
            with tabs.add_tab("Monitor"):
                self._monitoring(viewer, client, session, notify)
            with tabs.add_tab("Commission"):
                self.wizard = WizardPanel(gui, site, session, notify)
                self.commission = CommissionPanel(client, site, session, notify)
                repo = site.map_history()
                if repo is not None:
                    self.history = HistoryPanel(gui, repo, session, notify)
                upkeep = site.map_proposals()
                if upkeep is not None:
                    self.proposals = ProposalsPanel(gui, upkeep, session, notify)
                self.calibration = CalibrationPanel(gui, site, session, notify)
                if site.floorplan() is not None:
                    self.floorplan = FloorPlanPanel(gui, self._plan_of(viewer), bounds, notify)
            with tabs.add_tab("Survey"):
                self.survey = SurveyPanel(client, site, session, notify)
        else:
            self._monitoring(viewer, client, session, notify)

    @staticmethod
    def _plan_of(viewer: Viewer) -> Callable[[], FloorPlanStore]:
        """The plan store of the floor shown (the floor selector changes it)."""

        def store() -> FloorPlanStore:
            found = viewer.site.floorplan()
            if found is None:
                raise ValueError("this site keeps no floor plan")
            return found

        return store

    def _monitoring(
        self,
        viewer: Viewer,
        client: viser.ClientHandle,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        """Robots, events, batteries, recordings, zones, coverage, history playback."""
        site, gui = viewer.site, client.gui
        self.monitor = MonitorPanel(gui, site, session, viewer.history, notify)
        store = site.recordings()
        if store is not None and session.can_operate:
            robot = self.monitor.gui_robot
            self.recordings = RecordingsPanel(gui, store, session, lambda: robot.value, notify)
        zones = site.zones()
        if zones is not None:
            self.zones = ZonesPanel(client, zones, session, site.floor_shown, notify)
        self.coverage = CoveragePanel(client, site, notify)
        history = site.pose_history()
        if history is not None:
            names = [r.name for r in site.robots()]
            self.playback = PlaybackPanel(client, history, lambda: names, notify, site.floor_shown)

    def refresh(
        self,
        robots: Sequence[RobotState],
        landmarks: Sequence[LandmarkState],
        events: Sequence[EventLine],
    ) -> None:
        """Update every panel (the viewer's loop, at a few hertz)."""
        self.monitor.refresh(robots, landmarks, events)
        self.coverage.refresh(list(landmarks))
        self.inspect.refresh()
        for panel in (
            self.floor,
            self.wizard,
            self.survey,
            self.history,
            self.proposals,
            self.recordings,
            self.zones,
        ):
            if panel is not None:
                panel.refresh()
        for owner in (self.commission, self.history, self.floorplan):
            if owner is not None:
                owner.status.refresh()  # an action's status clears a while after it
