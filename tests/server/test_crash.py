"""`kill -9` of a real `irloc serve` during a stream of map edits loses no acknowledged
change; a restart resumes robots, map and keys."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import httpx
import pytest

from tests.server.served import free_port, serve

pytestmark = pytest.mark.slow


def test_kill_9_loses_no_acknowledged_map_change(tmp_path: Path) -> None:
    port = free_port()
    proc, lines = serve(tmp_path, port, "--log-level", "warning")
    base = f"http://127.0.0.1:{port}/api/v1"
    try:
        found = re.search(r"first admin API key .*: (\S+)", "".join(lines))
        assert found, "".join(lines)
        key = found.group(1)
        h = {"Authorization": f"Bearer {key}"}
        op_key = httpx.post(f"{base}/keys", json={"role": "operator"}, headers=h).json()["key"]
        acked: list[int] = []
        stop = threading.Event()

        def edit() -> None:
            with httpx.Client(timeout=5) as c:
                for i in range(10_000):
                    if stop.is_set():
                        return
                    body = {"id": 5000 + i, "x": 0.01 * i, "y": 1.0, "z": 2.5}
                    try:
                        r = c.post(f"{base}/landmarks", json=body, headers=h)
                    except httpx.HTTPError:
                        return
                    if r.status_code == 201:
                        acked.append(5000 + i)

        writer = threading.Thread(target=edit)
        writer.start()
        while len(acked) < 40:
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        stop.set()
        writer.join(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    proc2, lines2 = serve(tmp_path, port, "--log-level", "warning")
    try:
        assert "first admin API key" not in "".join(lines2)
        ids = {lm["id"] for lm in httpx.get(f"{base}/landmarks", headers=h).json()}
        assert set(acked) <= ids, sorted(set(acked) - ids)
        robots = httpx.get(f"{base}/robots", headers=h).json()
        assert [r["name"] for r in robots] == ["r1", "r2", "r3"]
        r = httpx.post(
            f"{base}/robots/r1/relocalize", headers={"Authorization": f"Bearer {op_key}"}
        )
        assert r.status_code == 202
    finally:
        proc2.send_signal(signal.SIGTERM)
        try:
            proc2.wait(20)
        except subprocess.TimeoutExpired:
            proc2.kill()
    # a graceful stop (uvicorn re-raises SIGTERM after its shutdown, hence -15): every LED
    # left on, the database closed (the last connection checkpointed and removed the WAL)
    assert proc2.returncode in (0, -signal.SIGTERM), "".join(lines2)
    assert "could not leave every LED on" not in "".join(lines2)
    assert not (tmp_path / "irloc.db-wal").exists()
