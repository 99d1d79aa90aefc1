"""A real `irloc serve` in a subprocess on a free loopback port, for tests that need the real
uvicorn (signals, handshakes, access logs)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def serve(data_dir: Path, port: int, *args: str) -> tuple[subprocess.Popen[str], list[str]]:
    """Start `irloc serve --data-dir D --port P --no-viewer ARGS` and wait for /healthz;
    returns the process and the list its output lines (stdout and stderr) are appended to."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "irloc", "serve", "--data-dir", str(data_dir),
         "--port", str(port), "--no-viewer", *args],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env=dict(os.environ),
    )  # fmt: skip
    lines: list[str] = []

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)

    threading.Thread(target=pump, daemon=True).start()
    url = f"http://127.0.0.1:{port}/healthz"
    for _ in range(300):
        try:
            if httpx.get(url, timeout=1).status_code == 200:
                return proc, lines
        except httpx.HTTPError:
            pass
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    proc.kill()
    raise AssertionError("irloc serve did not start:\n" + "".join(lines))


def first_admin_key(lines: list[str]) -> str:
    """The first admin key `irloc serve` printed on a fresh data folder."""
    marker = "first admin API key (shown once, store it): "
    return next(line.split(marker, 1)[1].strip() for line in lines if marker in line)
