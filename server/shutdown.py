"""`serve(config)`: run uvicorn so that SIGTERM (or Ctrl-C) always finishes, in seconds.

uvicorn on its own waits for every open connection before it runs the app's shutdown, and a
server-sent-event stream or a pose WebSocket never ends by itself: the shutdown steps (every
LED on, recordings closed, radio closed) never ran. Here, when the exit is requested:

1. the app's `draining` flag is set: event streams end with `event: shutdown`, pose
   WebSockets close with code 1001, and long work on threads (a lens calibration) stops at
   its next step (`stopping`, a `threading.Event`);
2. uvicorn closes idle connections and waits at most `grace_s` for the rest, then cancels
   them (a half-sent upload);
3. the app's lifespan shutdown runs (the site's stop: LEDs, recordings, radio), and one line
   says what state it left: `shutdown complete in 1.2 s: 39 of 39 LEDs lit, radio closed,
   1 recording closed`.
"""

from __future__ import annotations

import logging
import socket
import time
from typing import Any

import uvicorn

from server.stream_guard import draining, stopping

log = logging.getLogger(__name__)
GRACE_S = 3.0
"""How long open requests may take to finish once the exit is requested, seconds."""


class GracefulServer(uvicorn.Server):
    """A `uvicorn.Server` that ends the app's streams when asked to exit (see the module)."""

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        t0 = time.monotonic()
        app = self.config.loaded_app
        target = _innermost(app)
        services = getattr(target.state, "services", None) if target is not None else None
        recording = [] if services is None else _recording(services)
        gateway = None if services is None else getattr(services.leds, "gateway", None)
        if target is not None:
            stopping(target).set()
            draining(target).set()
        await super().shutdown(sockets)
        if services is not None:
            log.info(
                "shutdown complete in %.1f s: %s",
                time.monotonic() - t0,
                _summary(services, gateway, recording),
            )


def _innermost(app: Any) -> Any:
    """The FastAPI app inside uvicorn's middleware wrappers (they keep it in `.app`)."""
    seen = 0
    while app is not None and not hasattr(app, "state") and seen < 10:
        app = getattr(app, "app", None)
        seen += 1
    return app


def _recording(services: Any) -> list[str]:
    return [r.name for r in services.robots.runners() if getattr(r, "recorder", None) is not None]


def _summary(services: Any, gw: Any, recording: list[str]) -> str:
    if gw is None:
        radio = "no radio"
    else:
        lit = len(gw.leds.lit_among(gw.landmarks)) if gw.leds is not None else 0
        radio = f"{lit} of {len(gw.landmarks)} LEDs lit, radio {gw.transport.state}"
    still = [n for n in recording if n in _recording(services)]
    closed = len(recording) - len(still)
    text = f"{radio}, {closed} recording{'' if closed == 1 else 's'} closed"
    return text + (f", still open: {', '.join(still)}" if still else "")


def serve(config: uvicorn.Config, *, grace_s: float = GRACE_S) -> None:
    """Run `config`'s app until SIGTERM/SIGINT, then shut down within about `grace_s` plus
    the site's own stop."""
    config.timeout_graceful_shutdown = max(1, round(grace_s))
    GracefulServer(config).run()
