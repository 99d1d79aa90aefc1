"""Bounded connections at the HTTP edge: `ConnectionGuard` and the uvicorn protocol using it.

uvicorn on its own waits forever for a request's headers and accepts connections until the
process runs out of file descriptors (then every API call fails, without a log line). Here:

- A request's headers must arrive within `header_timeout_s` of its first byte (or of the
  connection's start): else the connection is closed.
- Connections still waiting for their headers ("pending") are capped per client address
  (`max_pending_per_address`): a new one closes that address's oldest pending connection,
  so half-sent requests cannot pile up and a good client (whose headers arrive at once) is
  never refused.
- All connections are capped (`max_connections`, lowered to the process's open-file limit
  less `FD_RESERVE` for the database, radio and logs), and per address
  (`max_per_address`: WebSockets and keep-alive connections count): past a cap the oldest
  pending connection goes first, and a new connection is closed only when none is pending.
- One warning line per burst (at most one per `LOG_EVERY_S`), with the counts.
"""

from __future__ import annotations

import asyncio
import logging
import resource
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Protocol

from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

log = logging.getLogger(__name__)
FD_RESERVE = 128
"""File descriptors kept for everything that is not an HTTP connection."""
LOG_EVERY_S = 10.0
MAX_HEADER_BYTES = 64 * 1024
"""A request line and headers longer than this are answered 400 and the connection closed."""


@dataclass(frozen=True)
class EdgeLimits:
    """Attributes:
    header_timeout_s: a request's headers must be complete this long after its first byte.
    max_pending_per_address: connections of one address still sending headers.
    max_per_address: open connections of one address (WebSockets included).
    max_connections: open connections in all (also capped by the open-file limit).
    """

    header_timeout_s: float = 10.0
    max_pending_per_address: int = 32
    max_per_address: int = 512
    max_connections: int = 4096


class _Closable(Protocol):
    def close_guarded(self) -> None: ...


def open_file_cap(limit: int, reserve: int = FD_RESERVE) -> int:
    """`limit`, lowered so that connections leave `reserve` descriptors of the soft limit."""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        return limit
    return max(16, min(limit, soft - reserve))


def raise_open_file_limit() -> int:
    """Raise the soft open-file limit to the hard one (services often start at 1,024);
    the soft limit in force."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != hard:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
            soft = hard
        except (ValueError, OSError):
            pass
    return soft


class ConnectionGuard:
    """The connection table of one server (event-loop thread only)."""

    def __init__(self, limits: EdgeLimits | None = None) -> None:
        self.limits = limits or EdgeLimits()
        self.open: dict[str, int] = {}
        self.total = 0
        self.pending: OrderedDict[_Closable, str] = OrderedDict()
        self.closed_slow = 0
        self.closed_for_cap = 0
        self.refused = 0
        self._logged_at = -LOG_EVERY_S
        self._unlogged = 0

    def _note(self, what: str, address: str) -> None:
        self._unlogged += 1
        now = time.monotonic()
        if now - self._logged_at >= LOG_EVERY_S:
            log.warning(
                "connection limits: %s (%s); %d such closes since the last line; "
                "%d open, %d still sending headers",
                what,
                address,
                self._unlogged,
                self.total,
                len(self.pending),
            )
            self._logged_at, self._unlogged = now, 0

    def _evict_oldest(self, address: str | None) -> bool:
        for conn, addr in self.pending.items():
            if address is None or addr == address:
                self.pending.pop(conn)
                self.closed_for_cap += 1
                conn.close_guarded()
                return True
        return False

    def admit(self, conn: _Closable, address: str) -> bool:
        """Count a new connection of `address`; False: it must be closed (nothing pending
        could make room)."""
        cap = open_file_cap(self.limits.max_connections)
        if self.total >= cap and not self._evict_oldest(None):
            self.refused += 1
            self._note(f"{cap} connections open, a new one refused", address)
            return False
        if self.open.get(address, 0) >= self.limits.max_per_address and not self._evict_oldest(
            address
        ):
            self.refused += 1
            self._note(f"{self.limits.max_per_address} connections of one address", address)
            return False
        self.open[address] = self.open.get(address, 0) + 1
        self.total += 1
        return True

    def waiting(self, conn: _Closable, address: str) -> None:
        """`conn` starts (or starts again) waiting for a request's headers."""
        if conn in self.pending:
            return
        mine = sum(1 for a in self.pending.values() if a == address)
        if mine >= self.limits.max_pending_per_address:
            self._evict_oldest(address)
            self._note("too many half-sent requests, the oldest closed", address)
        self.pending[conn] = address

    def headers_done(self, conn: _Closable) -> None:
        self.pending.pop(conn, None)

    def timed_out(self, conn: _Closable, address: str) -> None:
        if self.pending.pop(conn, None) is not None:
            self.closed_slow += 1
            self._note(f"headers not complete in {self.limits.header_timeout_s:g} s", address)
            conn.close_guarded()

    def gone(self, conn: _Closable, address: str, counted: bool) -> None:
        self.pending.pop(conn, None)
        if counted:
            self.total -= 1
            left = self.open.get(address, 1) - 1
            if left > 0:
                self.open[address] = left
            else:
                self.open.pop(address, None)


def guard_of(config: Any) -> ConnectionGuard:
    """The guard of a uvicorn config (its `edge_limits` attribute, else the defaults)."""
    guard: ConnectionGuard | None = getattr(config, "connection_guard", None)
    if guard is None:
        guard = config.connection_guard = ConnectionGuard(getattr(config, "edge_limits", None))
    return guard


class GuardedHttpProtocol(HttpToolsProtocol):
    """uvicorn's httptools protocol under a `ConnectionGuard` (see the module)."""

    def __init__(self, config: Any, *args: Any, **kwargs: Any) -> None:
        super().__init__(config, *args, **kwargs)
        self._guard = guard_of(config)
        self._address = "unknown"
        self._counted = False
        self._header_timer: asyncio.TimerHandle | None = None
        self._header_bytes = 0

    def close_guarded(self) -> None:
        self._stop_timer()
        if self.transport is not None and not self.transport.is_closing():
            self.transport.abort()

    def _stop_timer(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _wait_headers(self) -> None:
        self._guard.waiting(self, self._address)
        if self._header_timer is None:
            self._header_timer = self.loop.call_later(
                self._guard.limits.header_timeout_s, self._guard.timed_out, self, self._address
            )

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._address = self.client[0] if self.client else "unknown"
        if not self._guard.admit(self, self._address):
            transport.abort()
            return
        self._counted = True
        self._wait_headers()

    def data_received(self, data: bytes) -> None:
        waiting = self._header_timer is not None
        super().data_received(data)
        if waiting and self._header_timer is not None:  # still no complete headers
            self._header_bytes += len(data)
            if self._header_bytes > MAX_HEADER_BYTES:
                self._guard.headers_done(self)
                self._note_large_headers()

    def _note_large_headers(self) -> None:
        self._stop_timer()
        self._guard.closed_for_cap += 1
        self._guard._note(f"headers over {MAX_HEADER_BYTES} bytes", self._address)
        self.send_400_response("Request headers too large.")

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._wait_headers()

    def on_headers_complete(self) -> None:
        self._stop_timer()
        self._header_bytes = 0
        self._guard.headers_done(self)
        super().on_headers_complete()

    def handle_websocket_upgrade(self) -> None:
        super().handle_websocket_upgrade()
        # the WebSocket's protocol takes the transport: it is the one told of the close
        ws = self.transport.get_protocol()
        if ws is not self and self._counted:
            self._counted = False
            guard, address, lost = self._guard, self._address, ws.connection_lost

            def connection_lost(exc: Exception | None) -> None:
                guard.gone(self, address, True)
                lost(exc)

            ws.connection_lost = connection_lost  # type: ignore[method-assign]

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_timer()
        self._guard.gone(self, self._address, self._counted)
        self._counted = False
        super().connection_lost(exc)
