"""`SiteAlerts`: the site's alerts, checked twice a second on the server's loop and
delivered to every channel (docs/alerts.md).

Each check reads the site (`live.alert_watch.AlertWatch`), feeds the rules
(`live.alerts.AlertBook`: hold, clear and minimum-interval times) and hands each raised or
resolved notification to:

- the site events (`alert_raised`, `alert_resolved`: stored, on the SSE stream, logged),
- the listeners (the MQTT bridge publishes a retained message per active alert),
- the webhooks (`live.webhook.WebhookSender`, on their own threads), at most
  `alert_webhook_max_per_minute` a minute in all: past it notifications are counted, and one
  summary says how many were held back once the budget allows.

None of these waits: events and webhooks queue, the MQTT bridge queues on its loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable, Iterable
from datetime import datetime
from typing import Any

from live.alert_watch import AlertWatch, GatewayHost
from live.alerts import Alert, AlertBook, AlertConfig, Notification
from live.events import EventHub, EventKind
from live.robots import RobotRunner
from live.settings import Settings
from live.webhook import WebhookConfig, WebhookSender
from store.models import utcnow

log = logging.getLogger(__name__)
CHECK_S = 0.5


class SiteAlerts:
    """See the module. `runners()` lists the live robots; `leds` holds the gateway."""

    def __init__(
        self,
        settings: Settings,
        runners: Callable[[], Iterable[RobotRunner]],
        leds: GatewayHost,
        events: EventHub,
        *,
        clock: Callable[[], float] = time.monotonic,
        wall: Callable[[], datetime] = utcnow,
    ) -> None:
        s = settings
        self.site = s.mqtt_site
        self.events = events
        self.clock, self.wall = clock, wall
        self.book = AlertBook(
            AlertConfig(s.alert_raise_after_s, s.alert_clear_after_s, s.alert_min_interval_s)
        )
        self.watch = AlertWatch(runners, leds, stale_s=s.alert_stale_s, clock=clock)
        secret = s.alert_webhook_secret
        self.webhooks = WebhookSender(
            WebhookConfig(
                urls=tuple(s.alert_webhook_urls),
                timeout_s=s.alert_webhook_timeout_s,
                retries=s.alert_webhook_retries,
                secret=None if secret is None else secret.get_secret_value().encode(),
            )
        )
        self.max_per_minute = s.alert_webhook_max_per_minute
        self.raised = 0
        self.resolved = 0
        self.webhook_held = 0
        """Notifications not sent to the webhooks for the rate limit (in all)."""
        self._unsummed = 0
        self._tokens = float(self.max_per_minute)
        self._tokens_at = clock()
        self._listeners: tuple[Callable[[Notification], None], ...] = ()
        self._lock = threading.Lock()
        self._task: asyncio.Task[None] | None = None

    # -- reading ---------------------------------------------------------------------------
    def active(self) -> list[Alert]:
        """The active alerts, oldest first."""
        with self._lock:
            return self.book.active()

    def add_listener(self, listener: Callable[[Notification], None]) -> None:
        """Call `listener` with every notification (on the server's loop: it must not wait)."""
        self._listeners = (*self._listeners, listener)

    def remove_listener(self, listener: Callable[[Notification], None]) -> None:
        self._listeners = tuple(x for x in self._listeners if x is not listener)

    # -- checking --------------------------------------------------------------------------
    def check(self) -> list[Notification]:
        """One round: read the site, update the alerts, deliver what changed."""
        holding, unsure = self.watch.conditions()
        with self._lock:
            notes = self.book.update(self.clock(), self.wall(), holding, unsure)
        for note in notes:
            self._deliver(note)
        if self._unsummed and self._take_token():
            self._send_summary()
        return notes

    def _deliver(self, note: Notification) -> None:
        c = note.alert.condition
        body = note.to_dict(self.site)
        if note.state == "raised":
            self.raised += 1
        else:
            self.resolved += 1
        kind: EventKind = "alert_raised" if note.state == "raised" else "alert_resolved"
        self.events.emit(kind, note.message, robot=c.robot, landmark_id=c.landmark_id, data=body)
        for listener in self._listeners:
            try:
                listener(note)
            except Exception:
                log.exception("alert listener failed on %s", c.key)
        if self._take_token():
            self.webhooks.submit(body)
        else:
            self.webhook_held += 1
            self._unsummed += 1

    def _take_token(self) -> bool:
        if not self.webhooks.config.urls:
            return True
        now = self.clock()
        rate = self.max_per_minute / 60.0
        self._tokens = min(
            float(self.max_per_minute), self._tokens + (now - self._tokens_at) * rate
        )
        self._tokens_at = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

    def _send_summary(self) -> None:
        n, self._unsummed = self._unsummed, 0
        text = (
            f"[irloc {self.site}] {n} alert notification(s) not sent: more than "
            f"{self.max_per_minute} a minute; GET /api/v1/alerts lists the active alerts"
        )
        self.webhooks.submit({"state": "held_back", "count": n, "site": self.site, "text": text})

    def send_test(self) -> dict[str, Any]:
        """A test message to every webhook (to check a receiver); what was queued."""
        body = {
            "state": "test",
            "site": self.site,
            "text": f"[irloc {self.site}] test message: alerts reach this webhook",
            "t": self.wall().isoformat(),
        }
        self.webhooks.submit(body)
        return {"urls": len(self.webhooks.config.urls), "body": body}

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> None:
        self.webhooks.start()
        self._task = asyncio.get_running_loop().create_task(self._run())

    async def _run(self) -> None:
        while True:
            try:
                self.check()
            except Exception:
                log.exception("alerts: a check failed")
            await asyncio.sleep(CHECK_S)

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        await asyncio.to_thread(self.webhooks.stop, 2.0)
