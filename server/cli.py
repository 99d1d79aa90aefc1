"""`irloc serve`: run the API, the live site and the viewer.

With no arguments: the `demo` virtual site, the API on http://127.0.0.1:8000 and the viewer.
"""

from __future__ import annotations

import argparse
import socket
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from pydantic import ValidationError

from live.settings import Settings
from server.logs import configure_logging, redact
from server.loopback import is_loopback

if TYPE_CHECKING:
    import uvicorn

    from server.seams import ViewerApp


DEMOS = {"one-floor": "demo", "two-floors": "two_floors"}
"""`--demo NAME`: the scenario each demo runs."""


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
    p.add_argument(
        "--demo",
        choices=sorted(DEMOS),
        help="a demo site: one-floor (the default scenario) or two-floors (a lift between "
        "two floors)",
    )
    p.add_argument("--seed", type=int, help="virtual site seed")
    p.add_argument("--no-viewer", action="store_true", help="do not start the viewer")
    p.add_argument(
        "--mqtt", help="the site's MQTT broker, mqtt[s]://[USER@]HOST[:PORT]: robot agents"
    )
    p.add_argument(
        "--mqtt-password-file",
        type=Path,
        help="the broker password of USER (first line; else $IRLOC_MQTT_PASSWORD)",
    )
    p.add_argument("--mqtt-ca", type=Path, help="mqtts: the CA file that signed the broker")
    p.add_argument("--mqtt-cert", type=Path, help="mqtts: the server's client certificate")
    p.add_argument("--mqtt-key", type=Path, help="mqtts: its private key")
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


def _preflight(settings: Settings) -> str | None:
    """What would make the server fail once started, said in one line (None: nothing):
    the API's port taken, an unknown scenario. (They once failed after the ready banner and
    a new admin key were printed; the scenario with a 50-line traceback.)"""
    if settings.port != 0:
        with socket.socket(socket.AF_INET6 if ":" in settings.host else socket.AF_INET) as s:
            # as uvicorn binds: a port whose last server just died (TIME_WAIT) is free
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((settings.host, settings.port))
            except OSError as exc:
                return (
                    f"cannot listen on {settings.host}:{settings.port} ({exc.strerror}): another "
                    "server (another irloc serve?) has it; choose one with --port"
                )
    if settings.site_enabled:
        from sim.scenario import load_scenario

        try:
            load_scenario(settings.scenario)
        except ValueError as exc:
            return f"--scenario: {exc}"
    return None


def main(
    argv: list[str] | None = None, make_viewer: Callable[[Settings], ViewerApp | None] | None = None
) -> int:
    """`irloc serve`; `make_viewer(settings)` builds the viewer to serve (irloc/serve.py
    hands in `web.viewer.Viewer`; without it the API runs alone)."""
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    if args.demo is not None:
        if args.scenario is not None:
            print("irloc serve: give --demo or --scenario, not both", file=sys.stderr)
            return 2
        args.scenario = DEMOS[args.demo]
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
            "mqtt_password_file": args.mqtt_password_file,
            "mqtt_ca_file": args.mqtt_ca,
            "mqtt_cert_file": args.mqtt_cert,
            "mqtt_key_file": args.mqtt_key,
        }.items()
        if v is not None
    }
    if args.no_viewer:
        overrides["viewer_enabled"] = False
    if args.no_sim_robots:
        overrides["sim_robots"] = False
    try:
        settings = Settings(**overrides)
    except ValidationError as exc:  # its text repeats the input: a password, maybe
        said = "; ".join(
            ".".join(str(p) for p in e["loc"]) + (": " if e["loc"] else "") + e["msg"]
            for e in exc.errors()
        )
        print(f"irloc serve: {redact(said)}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"irloc serve: {redact(str(exc))}", file=sys.stderr)
        return 2
    if settings.map_file is not None and not settings.map_file.is_file():
        print(f"irloc serve: --map {settings.map_file}: no such file", file=sys.stderr)
        return 2
    problem = _preflight(settings)
    if problem is not None:  # before the banner and before a new admin key is made
        print(f"irloc serve: {problem}", file=sys.stderr)
        return 2
    configure_logging(args.log_level, settings.log_format)

    from sqlalchemy.exc import SQLAlchemyError

    from live.services import prepare_database
    from server.main import create_app
    from store.db import DatabaseFileError, make_engine

    try:
        engine = make_engine(settings.db_url)
        first_key = prepare_database(engine)
        engine.dispose()
    except DatabaseFileError as exc:
        print(f"irloc serve: {exc}", file=sys.stderr)
        return 2
    except SQLAlchemyError as exc:
        first = str(getattr(exc, "orig", None) or exc).splitlines()[0]
        print(f"irloc serve: database {redact(settings.db_url)}: {first}", file=sys.stderr)
        return 2
    viewer = make_viewer(settings) if make_viewer is not None else None
    from server.console import leds_line, startup_lines

    lines = startup_lines(
        host=settings.host,
        port=settings.port,
        data_dir=settings.data_dir,
        viewer_enabled=viewer is not None,
        first_key=first_key,
    )
    print("\n".join(lines[:-1] if first_key is not None else lines))
    if not is_loopback(settings.host):
        print(
            f"irloc: the API listens on {settings.host}, beyond this machine: every endpoint "
            "and the viewer need an API key; viser itself stays on 127.0.0.1"
        )
    if settings.site_enabled:
        print(leds_line(settings.led_policy, settings.radio_sleep_period_s))
    if settings.mqtt_url:
        broker = settings.broker()
        print(f"irloc: fleet     {broker} (site {settings.mqtt_site!r})")
        if broker.username is None and not settings.mqtt_agents:
            print(
                "irloc: the broker is open (no login) and no agent is admitted by name: "
                "agents' LED requests are not served (set mqtt_agents, or log in: "
                "docs/fleet.md)"
            )
    if first_key is not None:
        print(lines[-1])  # the key, last: easy to spot
    sys.stdout.flush()
    config = uvicorn_config(settings, create_app(settings, viewer), args.log_level)
    from server.shutdown import serve

    serve(config)
    return 0


def uvicorn_config(settings: Settings, app: object, log_level: str = "info") -> uvicorn.Config:
    """uvicorn's configuration of `irloc serve`: the guarded HTTP protocol (header timeout,
    connection caps: `server.connections`), forwarded-for headers only from
    `trusted_proxies` (uvicorn believes loopback's by default), the open-file limit raised."""
    import uvicorn

    from server.connections import (
        EdgeLimits,
        GuardedHttpProtocol,
        guard_of,
        raise_open_file_limit,
    )

    raise_open_file_limit()
    config = uvicorn.Config(
        app,  # type: ignore[arg-type]
        host=settings.host,
        port=settings.port,
        workers=1,
        log_level=log_level,
        log_config=None,  # uvicorn's loggers go through configure_logging's handler
        lifespan="on",
        http=GuardedHttpProtocol,
        proxy_headers=bool(settings.trusted_proxies),
        forwarded_allow_ips=list(settings.trusted_proxies) or None,
    )
    config.edge_limits = EdgeLimits(  # type: ignore[attr-defined]  # read by guard_of
        header_timeout_s=settings.header_timeout_s,
        max_per_address=settings.max_connections_per_address,
        max_connections=settings.max_connections,
    )
    state = getattr(app, "state", None)
    if state is not None:  # /metrics reads its counters
        state.connection_guard = guard_of(config)
    return config
