"""A real `irloc serve` (uvicorn, signals, JSON logs): SIGTERM with open event-stream,
WebSocket and upload clients exits within 10 s after the shutdown steps; refused WebSockets
get close code 1008 and a reason at the real handshake; no key in any log line."""

from __future__ import annotations

import json
import signal
import socket
import threading
import time
from pathlib import Path

import httpx
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.server.served import first_admin_key, free_port, serve

pytestmark = pytest.mark.slow


def _open_upload(port: int, key: str, robot: str) -> socket.socket:
    """A calibration upload that sends its headers and a little of its body, then stalls."""
    sock = socket.create_connection(("127.0.0.1", port))
    head = (
        f"POST /api/v1/robots/{robot}/calibration/lens HTTP/1.1\r\nHost: x\r\n"
        f"Authorization: Bearer {key}\r\n"
        "Content-Type: multipart/form-data; boundary=b0undary\r\nContent-Length: 5000000\r\n\r\n"
        '--b0undary\r\nContent-Disposition: form-data; name="files"; filename="a.png"\r\n'
        "Content-Type: image/png\r\n\r\n"
    )
    sock.sendall(head.encode() + b"\x89PNG" + b"\0" * 4000)
    return sock


def test_sigterm_with_open_clients_finishes_the_shutdown_steps_within_10_s(
    tmp_path: Path,
) -> None:
    port = free_port()
    proc, lines = serve(tmp_path, port, "--scenario", "paper_testbed", "--log-format", "json")
    base, ws_base = f"http://127.0.0.1:{port}", f"ws://127.0.0.1:{port}"
    sock = None
    try:
        key = first_admin_key(lines)
        auth = {"Authorization": f"Bearer {key}"}
        robot = httpx.get(f"{base}/api/v1/robots", headers=auth).json()[0]["name"]
        r = httpx.post(f"{base}/api/v1/robots/{robot}/recording/start", headers=auth)
        assert r.status_code == 200, r.text
        # refusals at the real handshake: accepted, then closed 1008 with the reason
        for url, reason in [
            (f"{ws_base}/api/v1/poses/ws?token=irloc_wrong", "a valid API key is required"),
            (f"{ws_base}/api/v1/robots/ghost/ws?token={key}", "robot 'ghost' is not running"),
        ]:
            with pytest.raises(ConnectionClosed) as exc, connect(url, open_timeout=5) as ws:
                ws.recv(timeout=5)
            assert exc.value.rcvd is not None and exc.value.rcvd.code == 1008, url
            assert reason in exc.value.rcvd.reason
        for path in ("/viewer/", "/api/v1/events?limit=1"):  # keys in the query, logged
            httpx.get(f"{base}{path}{'&' if '?' in path else '?'}token={key}")
        # the open clients: a pose WebSocket, an event stream, a stalled upload
        pose_ws = connect(f"{ws_base}/api/v1/poses/ws?token={key}", open_timeout=5)
        assert json.loads(pose_ws.recv(timeout=5))  # poses flow
        sse_text: list[str] = []

        def read_sse() -> None:
            with httpx.stream(
                "GET", f"{base}/api/v1/events/stream?token={key}", timeout=30
            ) as resp:
                for chunk in resp.iter_text():
                    sse_text.append(chunk)

        sse = threading.Thread(target=read_sse, daemon=True)
        sse.start()
        sock = _open_upload(port, key, robot)
        time.sleep(0.5)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=10)
        elapsed = time.monotonic() - t0
        sse.join(timeout=2)
        closed: ConnectionClosed | None = None
        try:
            while True:
                pose_ws.recv(timeout=2)
        except ConnectionClosed as exc:
            closed = exc
    finally:
        if proc.poll() is None:
            proc.kill()
        if sock is not None:
            sock.close()
    time.sleep(0.2)  # the output pump's last lines
    assert elapsed < 10.0
    logs = [json.loads(line) for line in lines if line.startswith("{")]
    done = [e["message"] for e in logs if e["message"].startswith("shutdown complete")]
    assert len(done) == 1, [e["message"] for e in logs[-15:]]
    assert "radio closed" in done[0] and "1 recording closed" in done[0]
    n_lit, n_all = (int(v) for v in done[0].split(": ")[1].split(" LEDs")[0].split(" of "))
    assert n_lit == n_all > 0  # every LED left on
    assert "event: shutdown" in "".join(sse_text)
    assert closed is not None and closed.rcvd is not None and closed.rcvd.code in (1001, 1012)
    # no key in any log line (the console's one-time print of the first key is not a log)
    access = [e["message"] for e in logs if e["logger"] == "uvicorn.access"]
    assert any("token=[redacted]" in m for m in access), access
    assert not [line for line in lines if key in line and "first admin API key" not in line]
    assert proc.returncode in (0, -signal.SIGTERM), proc.returncode
