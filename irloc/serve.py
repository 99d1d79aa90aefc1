"""`irloc serve`: the server with the viewer handed in (the one place that wires both).

`server.cli.main` parses the options and runs the API; this module adds the viewer
(`web.viewer.SiteViewer`), since the server itself never imports `web`.
"""

from __future__ import annotations

from live.settings import Settings
from server.cli import main as serve_main
from server.seams import ViewerApp


def make_viewer(settings: Settings) -> ViewerApp | None:
    """The viewer for `settings` (None when `viewer_enabled` is off), on a loopback port."""
    if not settings.viewer_enabled:
        return None
    from web.viewer import SiteViewer

    return SiteViewer(host="127.0.0.1", port=settings.viewer_port)


def main(argv: list[str] | None = None) -> int:
    return serve_main(argv, make_viewer=make_viewer)
