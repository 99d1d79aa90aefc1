"""The guarded HTTP protocol under a real uvicorn: half-sent requests are closed after the
header timeout and capped per address (the oldest goes, a good client always gets in),
connections are capped, oversized headers refused."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
import uvicorn

from server.connections import (
    MAX_HEADER_BYTES,
    ConnectionGuard,
    EdgeLimits,
    GuardedHttpProtocol,
    guard_of,
)


async def hello(scope: Any, receive: Any, send: Any) -> None:
    if scope["type"] == "lifespan":
        while (await receive())["type"] != "lifespan.shutdown":
            pass
        return
    await send({"type": "http.response.start", "status": 200, "headers": []})
    await send({"type": "http.response.body", "body": b"ok"})


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def served() -> Iterator[tuple[int, ConnectionGuard]]:
    port = free_port()
    config = uvicorn.Config(hello, host="127.0.0.1", port=port, http=GuardedHttpProtocol,
                            log_level="warning", lifespan="off")  # fmt: skip
    config.edge_limits = EdgeLimits(header_timeout_s=0.6, max_pending_per_address=8)  # type: ignore[attr-defined]
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.02)
    try:
        yield port, guard_of(config)
    finally:
        server.should_exit = True
        thread.join(10)


def closed(s: socket.socket, wait_s: float = 0.5) -> bool:
    s.settimeout(wait_s)
    try:
        return s.recv(1) == b""
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


def test_half_sent_requests_never_lock_out_a_good_client(
    served: tuple[int, ConnectionGuard],
) -> None:
    port, guard = served
    socks = []
    for _ in range(60):
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
        socks.append(s)
    time.sleep(0.1)
    t0 = time.monotonic()
    r = httpx.get(f"http://127.0.0.1:{port}/", timeout=5)
    assert r.status_code == 200 and time.monotonic() - t0 < 5.0  # not refused nor held
    assert len(guard.pending) <= 8 and guard.closed_for_cap >= 52
    assert closed(socks[0])  # the oldest went first
    time.sleep(0.8)  # past the header timeout: the rest are closed too
    assert all(closed(s, 0.2) for s in socks[-8:])
    assert guard.closed_slow >= 1 and not guard.pending
    for s in socks:
        s.close()


def test_a_slow_second_request_on_a_kept_alive_connection_is_timed_too(
    served: tuple[int, ConnectionGuard],
) -> None:
    port, _ = served
    s = socket.create_connection(("127.0.0.1", port))
    s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
    s.settimeout(2)
    assert b"200" in s.recv(4096)
    s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")  # never finished
    assert closed(s, 2.0)


def test_oversized_headers_are_refused(served: tuple[int, ConnectionGuard]) -> None:
    port, _ = served
    s = socket.create_connection(("127.0.0.1", port))
    s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
    for _ in range(MAX_HEADER_BYTES // 1000 + 2):
        s.sendall(b"X-Pad: " + b"a" * 990 + b"\r\n")
    s.settimeout(2)
    assert s.recv(4096).startswith(b"HTTP/1.1 400")


class Fake:
    def __init__(self) -> None:
        self.closed = False

    def close_guarded(self) -> None:
        self.closed = True


def test_connection_caps_evict_pending_first_then_refuse() -> None:
    guard = ConnectionGuard(EdgeLimits(max_per_address=3, max_pending_per_address=3))
    a, b, c = Fake(), Fake(), Fake()
    for conn in (a, b, c):
        assert guard.admit(conn, "1.2.3.4")
    guard.waiting(a, "1.2.3.4")
    d = Fake()
    assert guard.admit(d, "1.2.3.4") and a.closed  # a pending one made room
    guard.gone(a, "1.2.3.4", True)
    assert not guard.admit(Fake(), "1.2.3.4")  # nothing pending: the new one is refused
    assert guard.admit(Fake(), "5.6.7.8")  # another address is not affected
    assert guard.refused == 1
