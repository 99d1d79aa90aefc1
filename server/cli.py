"""`irloc serve`: run the API, the live site and the viewer.

With no arguments: the `demo` virtual site, the API on http://127.0.0.1:8000 and the viewer.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from pydantic import ValidationError

from live.settings import Settings
from server.logs import configure_logging
from server.loopback import is_loopback

if TYPE_CHECKING:
    from server.seams import ViewerApp


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="irloc serve", description=__doc__.splitlines()[0])
    p.add_argument("--host", help="API address (default 127.0.0.1)")
    p.add_argument("--port", type=int, help="API port (default 8000)")
    p.add_argument("--viewer-port", type=int, help="viser's own port on 127.0.0.1 (default 8080)")
    p.add_argument(
        "--data-dir", type=Path, help="database and recordings (default ~/.local/share/irloc)"
    )
    p.add_argument("--map", type=Path, dest="map_file", help="import this map.json at start")
    p.add_argument("--radio", help="sim | xbee:PORT[@BAUD] (default sim)")
    p.add_argument("--scenario", help="virtual site scenario name or file (default demo)")
    p.add_argument("--seed", type=int, help="virtual site seed")
    p.add_argument("--no-viewer", action="store_true", help="do not start the viewer")
    p.add_argument("--mqtt", help="the site's MQTT broker, mqtt://HOST[:PORT]: robot agents")
    p.add_argument(
        "--no-sim-robots", action="store_true", help="the virtual site's robots are not run here"
    )
    p.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])
    p.add_argument(
        "--log-format",
        choices=["text", "json"],
        help="text (default) or json: one JSON object a line (setting log_format)",
    )
    return p


def main(
    argv: list[str] | None = None, make_viewer: Callable[[Settings], ViewerApp | None] | None = None
) -> int:
    """`irloc serve`; `make_viewer(settings)` builds the viewer to serve (irloc/serve.py
    hands in `web.viewer.Viewer`; without it the API runs alone)."""
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    overrides = {
        k: v
        for k, v in {
            "host": args.host,
            "port": args.port,
            "viewer_port": args.viewer_port,
            "data_dir": args.data_dir,
            "map_file": args.map_file,
            "radio": args.radio,
            "scenario": args.scenario,
            "seed": args.seed,
            "log_format": args.log_format,
            "mqtt_url": args.mqtt,
        }.items()
        if v is not None
    }
    if args.no_viewer:
        overrides["viewer_enabled"] = False
    if args.no_sim_robots:
        overrides["sim_robots"] = False
    try:
        settings = Settings(**overrides)
    except (ValidationError, ValueError) as exc:
        print(f"irloc serve: {exc}", file=sys.stderr)
        return 2
    if settings.map_file is not None and not settings.map_file.is_file():
        print(f"irloc serve: --map {settings.map_file}: no such file", file=sys.stderr)
        return 2
    configure_logging(args.log_level, settings.log_format)
    import uvicorn

    from live.services import prepare_database
    from server.main import create_app
    from store.db import make_engine

    engine = make_engine(settings.db_url)
    first_key = prepare_database(engine)
    engine.dispose()
    viewer = make_viewer(settings) if make_viewer is not None else None
    from server.console import leds_line, startup_lines

    lines = startup_lines(
        host=settings.host, port=settings.port, data_dir=settings.data_dir,
        viewer_enabled=viewer is not None, first_key=first_key,
    )  # fmt: skip
    print("\n".join(lines[:-1] if first_key is not None else lines))
    if not is_loopback(settings.host):
        print(
            f"irloc: the API listens on {settings.host}, beyond this machine: every endpoint "
            "and the viewer need an API key; viser itself stays on 127.0.0.1"
        )
    if settings.site_enabled:
        print(leds_line(settings.led_policy, settings.radio_sleep_period_s))
    if settings.mqtt_url:
        print(f"irloc: fleet     {settings.mqtt_url} (site {settings.mqtt_site!r})")
    if first_key is not None:
        print(lines[-1])  # the key, last: easy to spot
    sys.stdout.flush()
    config = uvicorn.Config(
        create_app(settings, viewer),
        host=settings.host,
        port=settings.port,
        workers=1,
        log_level=args.log_level,
        log_config=None,  # uvicorn's loggers go through configure_logging's handler
        lifespan="on",
    )
    from server.shutdown import serve

    serve(config)
    return 0
