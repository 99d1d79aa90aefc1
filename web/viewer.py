"""`Viewer`: the viser app of a site, run inside the server process on its services.

It starts a viser server on a loopback port (viser has no login of its own: browsers reach
it through `web.proxy.viewer_router`, which checks the API key and hands the viewer a
one-time ticket naming the user's role), keeps the shared 3D scene in step with the site
from one thread at up to `rate_hz`, and builds each browser's GUI for its role.
"""

from __future__ import annotations

import contextlib
import io
import logging
import secrets
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import parse_qs, urlsplit

import numpy as np
import viser
from fastapi import APIRouter

from server.loopback import is_loopback
from server.seams import Authenticate
from store.errors import NotFoundError
from web.adapter import SiteAdapter
from web.client_panels import ClientPanels
from web.floorplan_view import FloorPlanLayer
from web.panels.inspect import LastUse
from web.panels.monitor import UncertaintyHistory
from web.roles import ANONYMOUS, TICKET_PARAM, Session
from web.scene import SiteScene
from web.services import LandmarkState, ViewerSite
from web.viser_compat import (
    ViserCompatError,
    check_viser,
    disable_share,
    guard_connections,
    refuse,
    request_header,
    request_path,
)
from web.zones_view import ZonesLayer

if TYPE_CHECKING:
    from live.services import SiteServices

log = logging.getLogger(__name__)
__all__ = ["TICKET_PARAM", "Viewer", "ViewerConfig"]


@dataclass(frozen=True)
class ViewerConfig:
    """Viewer settings.

    Attributes:
        rate_hz: robot updates per second (scene).
        landmark_rate_hz: landmark/LED refreshes per second.
        panel_rate_hz: table, plot and wizard refreshes per second.
        event_limit: events listed.
        ticket_ttl_s: a proxy ticket must be used within this time, seconds.
        margin_m: floor and ceiling grids extend this far beyond the landmarks, metres.
    """

    rate_hz: float = 30.0
    landmark_rate_hz: float = 2.0
    panel_rate_hz: float = 2.0
    event_limit: int = 15
    ticket_ttl_s: float = 60.0
    margin_m: float = 2.0


class Viewer:
    """The site's 3D viewer.

    A `server.seams.ViewerApp`: `irloc serve` builds it and hands it to `create_app`, which
    includes `router(authenticate)` and calls `start(services)` with the running
    `SiteServices` (seen through `web.adapter.SiteAdapter`). Tests hand any
    `web.services.ViewerSite` to the constructor and call `start()`.

    Args:
        site: the site to show (None: the services given to `start`).
        host: viser's bind address; only loopback is accepted (use the proxy).
        port: viser's port; 0 picks a free one (read `port` after `start`).
        config: rates and limits.

    Raises:
        ValueError: for a non-loopback `host`.
    """

    def __init__(
        self,
        site: ViewerSite | None = None,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        config: ViewerConfig | None = None,
    ) -> None:
        if not is_loopback(host):
            raise ValueError(
                f"viewer: refusing to expose viser on {host!r}: it has no login of its own. "
                "Bind it to 127.0.0.1 and open it through the API's /viewer/ page (API key)"
            )
        self.host, self._port = host, port
        self.config = config or ViewerConfig()
        self._given = site
        self.services: SiteServices | None = None
        self.site: ViewerSite
        self._adapter: SiteAdapter | None = None
        self.server: viser.ViserServer | None = None
        self.scene: SiteScene | None = None
        self.floorplan: FloorPlanLayer | None = None
        self.history = UncertaintyHistory()
        self.last_use = LastUse()
        """Which robot last used each landmark (the inspect panel's "last used")."""
        self.zones: ZonesLayer | None = None
        self._floor_drawn: str | None = None
        self._tickets: dict[str, tuple[float, Session]] = {}
        self._sessions: dict[int, Session] = {}
        self._panels: dict[int, ClientPanels] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.ticks = 0
        self.share_refusals = 0
        """viser share requests refused (crafted clients: the button is hidden)."""

    @property
    def port(self) -> int:
        """viser's real port (after `start`)."""
        return self.server.get_port() if self.server is not None else self._port

    # -- lifecycle ---------------------------------------------------------------------------
    def router(self, authenticate: Authenticate) -> APIRouter:
        """The `/viewer/` routes (web.proxy) for this viewer, behind the API key check."""
        from web.proxy import viewer_router

        return viewer_router(lambda: self if self.server is not None else None, authenticate)

    def start(self, services: SiteServices | None = None) -> None:
        """Start viser, build the scene and the update thread (on `services`, else on the
        site given to the constructor)."""
        self.services = services  # its map and floor plan stores, for the panels that edit them
        if services is not None:
            self._adapter = SiteAdapter(services)
            self.site = self._adapter
        elif self._given is not None:
            self.site = self._given
        else:
            raise ValueError("viewer: no site to show (give one, or start it with services)")
        self.server = _start_viser(self.host, self._port)
        try:
            check_viser(self.server)
            guard_connections(self.server, self._admit)
        except ViserCompatError as exc:  # every browser will be refused
            log.error("viewer: %s", exc)
        try:
            disable_share(self.server, self._share_refused)
        except ViserCompatError as exc:  # no tunnel can be refused: stop here
            self.server.stop()
            self.server = None
            raise RuntimeError(f"viewer: {exc}") from exc
        self.server.gui.configure_theme(show_share_button=False, control_width="medium")
        self.scene = SiteScene(self.server)
        self.scene.on_pick = self._picked
        lms = self.site.landmarks()
        self._floor_drawn = self.site.floor_shown()
        self.scene.set_site(self._extent(lms), self.site.ceiling_height())
        self.scene.update_landmarks(lms, self.site.lit())
        store = self.site.floorplan()
        self.floorplan = None if store is None else FloorPlanLayer(self.server.scene, store)
        zones = self.site.zones()
        self.zones = None if zones is None else ZonesLayer(self.server.scene, zones)
        if self.zones is not None:
            self.zones.refresh(self._floor_drawn)
        self.server.on_client_connect(self._on_connect)
        self.server.on_client_disconnect(self._on_disconnect)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="irloc-viewer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the update thread and viser (the identification wizard is the server's)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self.server is not None:
            self.server.stop()
            self.server = None
        if self._adapter is not None:
            self._adapter.close()

    def _extent(self, lms: list[LandmarkState]) -> tuple[float, float, float, float]:
        """The floor's extent: its landmarks and `margin_m` around them, metres."""
        pos = np.array([[lm.x, lm.y] for lm in lms]).reshape(-1, 2)
        m = self.config.margin_m
        lo = pos.min(axis=0) - m if len(pos) else np.array([-5.0, -5.0])
        hi = pos.max(axis=0) + m if len(pos) else np.array([5.0, 5.0])
        return (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))

    def _picked(self, client_id: int, kind: str, key: str) -> None:
        """A landmark or robot clicked in a browser: its inspect panel shows it."""
        with self._lock:
            panels = self._panels.get(client_id)
        if panels is not None:
            panels.inspect.select(kind, key)

    def _follow_floor(self) -> None:
        """The floor shown changed: its extent, ceiling, plan and zones."""
        assert self.scene is not None  # started
        floor = self.site.floor_shown()
        if floor != self._floor_drawn:
            self._floor_drawn = floor  # its landmarks read after the floor: never the last's
            self.scene.set_site(self._extent(self.site.landmarks()), self.site.ceiling_height())
        store = self.site.floorplan()
        if self.floorplan is not None and store is not None:
            self.floorplan.follow(store)
        if self.zones is not None:
            self.zones.refresh(floor)

    # -- sessions ------------------------------------------------------------------------------
    def issue_ticket(self, session: Session) -> str:
        """A one-time ticket for the proxy to put in viser's WebSocket URL
        (`?irloc_ticket=...`): the browser that connects with it gets `session`."""
        ticket = secrets.token_urlsafe(24)
        now = time.monotonic()
        with self._lock:
            self._tickets = {
                k: v for k, v in self._tickets.items() if now - v[0] < self.config.ticket_ttl_s
            }
            self._tickets[ticket] = (now, session)
        return ticket

    def _session_for(self, client: viser.ClientHandle) -> Session:
        assert self.server is not None  # started
        try:
            path = request_path(self.server, client)
        except ViserCompatError as exc:
            log.error("viewer: %s", exc)
            return ANONYMOUS
        if path is None:
            return ANONYMOUS
        ticket = parse_qs(urlsplit(path).query).get(TICKET_PARAM, [""])[0]
        with self._lock:
            hit = self._tickets.pop(ticket, None)
        if hit is None or time.monotonic() - hit[0] > self.config.ticket_ttl_s:
            return ANONYMOUS
        return hit[1]

    def _admit(self, path: str | None, origin: str | None) -> str | None:
        """None for the proxy's connection (a live ticket, no Origin header), else why not:
        any other process on the host, or a web page in a browser on it, is refused."""
        if origin is not None:
            return "cross-origin connection refused: open /viewer/ on the API's port"
        ticket = parse_qs(urlsplit(path or "").query).get(TICKET_PARAM, [""])[0]
        with self._lock:
            hit = self._tickets.get(ticket)
        if hit is None or time.monotonic() - hit[0] > self.config.ticket_ttl_s:
            return "open the viewer through /viewer/ with an API key"
        return None

    def _has_origin(self, client: viser.ClientHandle) -> bool:
        assert self.server is not None  # started
        try:
            return request_header(self.server, client, "origin") is not None
        except ViserCompatError:
            return True  # cannot tell: refuse

    def recording_zip(self, name: str) -> Path:
        """A recording zipped into a temporary file (the caller deletes it), for the
        viewer's download link; NotFoundError, ConflictError (still being written)."""
        store = self.site.recordings()
        if store is None:
            raise NotFoundError("this site keeps no recordings")
        return store.catalog.zip_file(name)

    def _share_refused(self, client_id: int) -> None:
        """A browser sent viser's share request (the button is hidden: a crafted client)."""
        self.share_refusals += 1
        log.warning(
            "viewer: refused viser's share tunnel requested by client %s (%s)",
            client_id,
            self.session_of(client_id) or "no session",
        )

    def session_of(self, client_id: int) -> Session | None:
        """The session of a connected browser."""
        with self._lock:
            return self._sessions.get(client_id)

    def _on_connect(self, client: viser.ClientHandle) -> None:
        # a web page (it sends an Origin) is refused before its ticket is looked at: it must
        # not spend the proxy's one-time ticket (the connection layer's `_admit` and this
        # callback race; either may see the connection first)
        session = ANONYMOUS if self._has_origin(client) else self._session_for(client)
        if session is ANONYMOUS:
            # viser's own port: only the proxy (a valid one-time ticket, no Origin header as a
            # browser would send) gets in; any other local process or web page is refused
            assert self.server is not None  # started
            refuse(self.server, client, "open the viewer through /viewer/ with an API key")
            return
        with self._lock:
            self._sessions[client.client_id] = session
        assert self.server is not None  # started
        panels = None
        try:
            panels = ClientPanels(self, client, session)
        except Exception:
            if client.client_id in self.server.get_clients():
                raise  # a bug in a panel, not a browser that left
            log.debug("viewer: client %s left while its panels were built", client.client_id)
        finally:
            with self._lock:
                if panels is not None and client.client_id in self.server.get_clients():
                    self._panels[client.client_id] = panels
                else:  # it left while its panels were built (or building failed): forget it
                    self._sessions.pop(client.client_id, None)

    def _on_disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._sessions.pop(client.client_id, None)
            self._panels.pop(client.client_id, None)

    # -- the update loop ---------------------------------------------------------------------
    def _run(self) -> None:
        cfg = self.config
        period = 1.0 / cfg.rate_hz
        next_lm = next_panel = 0.0
        while not self._stop.is_set():
            t0 = time.monotonic()
            try:
                self._tick(t0 >= next_lm, t0 >= next_panel)
            except Exception:  # keep the viewer alive; the site may be restarting
                log.exception("viewer: update failed")
            if t0 >= next_lm:
                next_lm = t0 + 1.0 / cfg.landmark_rate_hz
            if t0 >= next_panel:
                next_panel = t0 + 1.0 / cfg.panel_rate_hz
            self._stop.wait(max(0.0, period - (time.monotonic() - t0)))

    def _tick(self, landmarks_due: bool, panels_due: bool) -> None:
        assert self.server is not None and self.scene is not None  # started
        robots = self.site.robots()
        lms = self.site.landmarks() if landmarks_due or panels_due else None
        if self.scene.robots_changed(robots) or landmarks_due:  # else nothing to send
            with self.server.atomic():
                self.scene.update_robots(robots)
                if landmarks_due and lms is not None:
                    self.scene.update_landmarks(lms, self.site.lit())
        self.last_use.add(robots)
        if landmarks_due:
            self._follow_floor()
        if landmarks_due and self.floorplan is not None:
            self.floorplan.refresh()
        with self._lock:
            following = [p.view for p in self._panels.values()]
        names = [r.name for r in robots]
        for view in following:
            try:
                view.set_robots(names)  # robots that joined since the panel was built
                view.follow(robots, time.monotonic())
            except Exception:  # its browser went away mid-update
                log.debug("viewer: follow failed", exc_info=True)
        if panels_due and lms is not None:
            self.history.add(robots)
            events = self.site.events(self.config.event_limit)
            with self._lock:
                panels = list(self._panels.items())
            for cid, p in panels:
                try:
                    p.refresh(robots, lms, events)
                except Exception:  # its browser went away mid-update
                    log.debug("viewer: dropping the panels of client %s", cid, exc_info=True)
                    with self._lock:
                        self._panels.pop(cid, None)
        self.ticks += 1


def _start_viser(host: str, port: int) -> viser.ViserServer:
    """Start viser without its banner: viser 1.1 prints its own URL to stdout even with
    `verbose=False`, and that URL is the loopback port behind the proxy, not the one users
    should open (the server prints `/viewer/?token=...`); the banner goes to the debug log."""
    banner = io.StringIO()
    with contextlib.redirect_stdout(banner):
        server = viser.ViserServer(host, port, label="irloc", verbose=False)
    log.debug("viser started on %s:%d: %s", host, port, banner.getvalue().strip())
    return server
