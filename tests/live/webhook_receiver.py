"""A real HTTP server on a free loopback port that records the JSON POSTed to it (a webhook
receiver for tests): `with Receiver([500, 200]) as r: ... r.url ... r.bodies`."""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import TracebackType
from typing import Any


class Receiver:
    """Answers each POST with the next status of `answers` (then 200), after `delay_s`."""

    def __init__(self, answers: list[int] | None = None, delay_s: float = 0.0) -> None:
        self.answers = list(answers or [])
        self.delay_s = delay_s
        self.bodies: list[dict[str, Any]] = []
        self.headers: list[dict[str, str]] = []
        self.tries = 0
        self.got = threading.Condition()
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:
                raw = self.rfile.read(int(self.headers.get("Content-Length", "0")))
                if receiver.delay_s:
                    threading.Event().wait(receiver.delay_s)
                with receiver.got:
                    receiver.tries += 1
                    code = receiver.answers.pop(0) if receiver.answers else 200
                    if code < 300:
                        receiver.bodies.append(json.loads(raw))
                        receiver.headers.append(dict(self.headers.items()))
                    receiver.got.notify_all()
                self.send_response(code)
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *args: object) -> None:
                return None

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/hook"
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def wait_for(self, n: int, timeout_s: float = 10.0) -> list[dict[str, Any]]:
        """The bodies once `n` were received (AssertionError on timeout)."""
        with self.got:
            if not self.got.wait_for(lambda: len(self.bodies) >= n, timeout_s):
                raise AssertionError(f"{len(self.bodies)} of {n} webhook bodies: {self.bodies}")
            return list(self.bodies)

    def __enter__(self) -> Receiver:
        self._thread.start()
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.server.shutdown()
        self.server.server_close()
