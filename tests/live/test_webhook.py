"""Webhook delivery against a real local HTTP server: retries with backoff, the signature,
a dead or slow receiver that holds up nothing."""

from __future__ import annotations

import json
import time

from live.webhook import WebhookConfig, WebhookSender, signature
from tests.fleet.mosquitto import free_port
from tests.live.webhook_receiver import Receiver


def test_a_failing_receiver_is_retried_until_it_takes_the_body_signed() -> None:
    with Receiver([503, 500]) as rx:
        sender = WebhookSender(
            WebhookConfig(urls=[rx.url], backoff_s=0.05, retries=3, secret=b"s3cret")
        )
        sender.start()
        sender.submit({"state": "raised", "key": "robot_lost:r1"})
        (body,) = rx.wait_for(1)
        sender.stop()
    assert body == {"state": "raised", "key": "robot_lost:r1"}
    assert rx.tries == 3 and sender.stats.retries == 2 and sender.stats.delivered == 1
    raw = json.dumps(body).encode()
    assert rx.headers[0]["X-Irloc-Signature"] == signature(b"s3cret", raw)


def test_a_refusing_receiver_is_not_retried_and_a_dead_one_is_given_up() -> None:
    dead = f"http://127.0.0.1:{free_port()}/nobody"
    with Receiver([400]) as rx:
        sender = WebhookSender(WebhookConfig(urls=[rx.url, dead], backoff_s=0.02, retries=2))
        sender.start()
        sender.submit({"n": 1})
        sender.submit({"n": 2})
        assert [b["n"] for b in rx.wait_for(1)] == [2]  # 1 refused (400): not retried
        deadline = time.monotonic() + 10
        while sender.stats.failed < 3 and time.monotonic() < deadline:
            time.sleep(0.02)
        sender.stop()
    assert rx.tries == 2
    assert sender.stats.failed == 3  # the 400, and both bodies to the dead URL
    assert sender.stats.retries == 4  # the dead URL: 2 retries per body


def test_a_slow_receiver_never_blocks_the_caller_and_the_queue_is_bounded() -> None:
    with Receiver(delay_s=0.5) as rx:
        sender = WebhookSender(WebhookConfig(urls=[rx.url], queue_items=4, timeout_s=5))
        sender.start()
        t0 = time.monotonic()
        for n in range(50):
            sender.submit({"n": n})
        took = time.monotonic() - t0
        received = rx.wait_for(2)
        sender.stop(timeout_s=0.1)
    assert took < 0.2, took
    assert sender.stats.dropped >= 40  # the oldest went; the newest are kept
    assert received[0]["n"] == 0 or received[0]["n"] >= 45
