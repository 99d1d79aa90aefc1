"""`WebhookSender`: POSTs JSON bodies (alert notifications) to configured URLs, each URL on
its own thread with its own bounded queue, so a slow or dead receiver never holds up the
site, the other URLs or the caller (`submit` only queues).

Each body is tried `1 + retries` times: a connection error, a timeout, 408, 429 or a 5xx
answer is retried after `backoff_s`, doubling up to `max_backoff_s` (a 429's or 503's
`Retry-After` in seconds is honoured within that bound); any other answer (2xx: delivered;
other 4xx: the receiver refuses it, retrying would not help) ends the tries. A full queue
drops the oldest body (counted). With a `secret`, each request carries
`X-Irloc-Signature: sha256=<hex HMAC-SHA256 of the body>` for the receiver to check.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import queue
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import httpx

log = logging.getLogger(__name__)
RETRY_STATUS = frozenset({408, 429, 500, 502, 503, 504})


@dataclass(frozen=True)
class WebhookConfig:
    """Attributes:
    urls: where to POST (http or https).
    timeout_s: connect and read timeout of one try.
    retries: tries after the first.
    backoff_s, max_backoff_s: the pause before the first retry, and its bound (doubling).
    queue_items: bodies waiting per URL before the oldest is dropped.
    secret: key of the `X-Irloc-Signature` HMAC (None: no signature).
    """

    urls: Sequence[str] = ()
    timeout_s: float = 5.0
    retries: int = 5
    backoff_s: float = 1.0
    max_backoff_s: float = 60.0
    queue_items: int = 256
    secret: bytes | None = None


@dataclass
class WebhookStats:
    """Counters over every URL (read by `/metrics`)."""

    delivered: int = 0
    failed: int = 0
    retries: int = 0
    dropped: int = 0


def signature(secret: bytes, body: bytes) -> str:
    """The `X-Irloc-Signature` value of `body`."""
    return "sha256=" + hmac.new(secret, body, hashlib.sha256).hexdigest()


class _Target:
    """One URL: its queue and thread."""

    def __init__(self, url: str, sender: WebhookSender, index: int) -> None:
        self.url = url
        self.sender = sender
        self.queue: queue.Queue[bytes | None] = queue.Queue(sender.config.queue_items)
        self.thread = threading.Thread(target=self._run, name=f"webhook-{index}", daemon=True)

    def put(self, body: bytes) -> None:
        while True:
            try:
                self.queue.put_nowait(body)
                return
            except queue.Full:
                try:
                    self.queue.get_nowait()
                    self.sender.stats.dropped += 1
                except queue.Empty:
                    pass

    def _run(self) -> None:
        cfg = self.sender.config
        with httpx.Client(timeout=cfg.timeout_s, follow_redirects=False) as client:
            while (body := self.queue.get()) is not None:
                self._deliver(client, body)

    def _deliver(self, client: httpx.Client, body: bytes) -> None:
        cfg, stats, stop = self.sender.config, self.sender.stats, self.sender.stopping
        headers = {"Content-Type": "application/json", "User-Agent": "irloc-alerts"}
        if cfg.secret is not None:
            headers["X-Irloc-Signature"] = signature(cfg.secret, body)
        pause = cfg.backoff_s
        problem = ""
        for attempt in range(1 + cfg.retries):
            if attempt:
                stats.retries += 1
                if stop.wait(pause):  # stopping: what is left is not sent
                    break
                pause = min(cfg.max_backoff_s, pause * 2)
            try:
                answer = client.post(self.url, content=body, headers=headers)
            except httpx.HTTPError as exc:
                problem = f"{type(exc).__name__}: {exc}"
                continue
            if answer.status_code < 300:
                stats.delivered += 1
                return
            problem = f"answered {answer.status_code}"
            if answer.status_code not in RETRY_STATUS:
                break
            after = answer.headers.get("retry-after", "")
            if after.isdigit():
                pause = min(cfg.max_backoff_s, max(pause, float(after)))
        stats.failed += 1
        log.warning("webhook %s: not delivered (%s)", self.url, problem)


class WebhookSender:
    """See the module. `start()` once, `submit(body)` from any thread, `stop()` at the end."""

    def __init__(self, config: WebhookConfig) -> None:
        self.config = config
        self.stats = WebhookStats()
        self.stopping = threading.Event()
        self._targets = [_Target(url, self, i) for i, url in enumerate(config.urls)]

    def start(self) -> None:
        for target in self._targets:
            target.thread.start()

    def submit(self, body: dict[str, Any] | bytes) -> None:
        """Queue one JSON body for every URL (never blocks)."""
        data = body if isinstance(body, bytes) else json.dumps(body).encode()
        for target in self._targets:
            target.put(data)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Send what is queued within `timeout_s` (no more retry pauses), then end."""
        self.stopping.set()
        for target in self._targets:
            try:
                target.queue.put(None, timeout=timeout_s)
            except queue.Full:
                continue
        for target in self._targets:
            if target.thread.is_alive():
                target.thread.join(timeout_s)
