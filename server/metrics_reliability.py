"""The reliability counters on `/metrics`: what the site refused, dropped, restarted or could
not store, read at scrape time from the parts that count them (docs/api.md, "Operations").

- HTTP edge (`server.edge.EdgeGuard`): refusals by status, bodies too large, bodies
  without a key; connections (`server.connections.ConnectionGuard`, under `irloc serve`):
  open, closed for a slow header or a cap, refused; bad keys and throttled addresses.
- Storage: site events written, failed writes, dropped, whether the database takes events
  now (`live.event_writer`); each robot's live recording's dropped frames, samples and late
  items (`live.recording_queue`).
- Site threads restarted by the supervisor, and the problems `/healthz` names now.
- The fleet link (`live.mqtt_bridge`): connections, messages received and rejected, LED
  requests refused, foreign maps, poses outside the site, agents refused, agents' pose
  messages lost.
- Alerts: active ones by kind, notifications by state, webhook deliveries.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from starlette.datastructures import State

from live.agent_runner import AgentRunner
from live.alerts import ALERT_KINDS

if TYPE_CHECKING:
    from live.mqtt_bridge import MqttBridge
    from live.services import SiteServices


def _counter(name: str, doc: str, value: float) -> CounterMetricFamily:
    return CounterMetricFamily(name, doc, value=value)


def _gauge(name: str, doc: str, value: float) -> GaugeMetricFamily:
    return GaugeMetricFamily(name, doc, value=value)


def edge_metrics(state: State | None) -> Iterator[Metric]:
    """The HTTP edge: the guard's refusals, connections, bad keys."""
    edge = getattr(state, "edge_counters", None)
    refused = CounterMetricFamily(
        "irloc_edge_refusals", "requests refused at the HTTP edge", labels=["status"]
    )
    if edge is not None:
        for code, n in sorted(edge.by_status.items()):
            refused.add_metric([str(code)], n)
        yield _counter(
            "irloc_edge_bodies_too_large", "bodies over their limit (413)", edge.too_large
        )
        yield _counter(
            "irloc_edge_bodies_without_key",
            "bodies sent without a valid key",
            edge.body_without_key,
        )
    yield refused
    guard = getattr(state, "connection_guard", None)
    if guard is not None:
        yield _gauge("irloc_connections_open", "open HTTP connections", guard.total)
        yield _counter(
            "irloc_connections_closed_slow", "closed: headers not sent in time", guard.closed_slow
        )
        yield _counter(
            "irloc_connections_closed_for_cap",
            "closed to make room under a cap",
            guard.closed_for_cap,
        )
        yield _counter(
            "irloc_connections_refused", "refused: a connection cap was reached", guard.refused
        )
    throttle = getattr(state, "key_throttle", None)
    yield _counter(
        "irloc_bad_keys", "requests with a bad API key", 0 if throttle is None else throttle.bad
    )
    yield _counter(
        "irloc_bad_keys_throttled",
        "answers 429 to addresses sending bad keys",
        0 if throttle is None else throttle.throttled,
    )


def storage_metrics(s: SiteServices) -> Iterator[Metric]:
    """The event writer and the live recordings' queues."""
    w = s.events.writer
    yield _counter("irloc_events_written", "site events stored", w.written)
    yield _counter(
        "irloc_event_store_failures", "failed attempts to store an event", w.store_failures
    )
    yield _counter("irloc_events_dropped", "site events dropped (queue full)", w.dropped)
    yield _gauge(
        "irloc_event_store_ok", "1 while the database takes events, else 0", 1 if w.healthy else 0
    )
    labels = ["robot", "what"]
    drops = CounterMetricFamily(
        "irloc_recording_dropped",
        "items a live recording dropped (frames or samples: queue full; late: out of order)",
        labels=labels,
    )
    for r in s.robots.runners():
        rec = r.recorder
        if rec is not None:
            drops.add_metric([r.name, "frames"], rec.frames_dropped)
            drops.add_metric([r.name, "samples"], rec.samples_dropped)
            drops.add_metric([r.name, "late"], rec.late_dropped)
    yield drops


def site_metrics(s: SiteServices, state: State | None) -> Iterator[Metric]:
    """The supervisor, the fleet link, the alerts."""
    site = s.runner
    yield _counter(
        "irloc_site_thread_restarts",
        "site threads started again by the supervisor",
        0 if site is None else site.supervisor.restarts,
    )
    yield _gauge(
        "irloc_site_problems",
        "problems the live site reports now (/healthz)",
        0 if site is None else len(site.supervisor.problems()),
    )
    bridge: MqttBridge | None = getattr(state, "mqtt_bridge", None)
    if bridge is not None:
        guard = bridge.guard
        for name, doc, value in (
            ("irloc_mqtt_connects", "connections to the broker", bridge.connects),
            ("irloc_mqtt_received", "MQTT messages received", bridge.received),
            ("irloc_mqtt_rejected", "MQTT messages that did not fit their topic", bridge.rejected),
            (
                "irloc_mqtt_led_requests_refused",
                "agents' LED requests not served",
                guard.led_requests_refused,
            ),
            (
                "irloc_mqtt_foreign_maps",
                "maps on the map topic not published here",
                guard.foreign_maps,
            ),
            (
                "irloc_mqtt_poses_outside",
                "agents' poses outside the site, dropped",
                guard.poses_outside,
            ),
        ):
            yield _counter(name, doc, value)
        yield _gauge(
            "irloc_mqtt_agents_refused", "agents refused a place", len(guard.refused_agents)
        )
    lost = sum(r.lost_messages for r in s.robots.runners() if isinstance(r, AgentRunner))
    yield _counter(
        "irloc_agent_pose_messages_lost", "agents' pose messages missing (seq gaps)", lost
    )
    yield from alert_metrics(s)


def alert_metrics(s: SiteServices) -> Iterator[Metric]:
    alerts = s.alerts
    active = GaugeMetricFamily("irloc_alerts_active", "active alerts", labels=["kind"])
    counts = dict.fromkeys(ALERT_KINDS, 0)
    for a in alerts.active():
        counts[a.condition.kind] += 1
    for kind, n in counts.items():
        active.add_metric([kind], n)
    yield active
    notes = CounterMetricFamily(
        "irloc_alert_notifications", "alert notifications", labels=["state"]
    )
    notes.add_metric(["raised"], alerts.raised)
    notes.add_metric(["resolved"], alerts.resolved)
    yield notes
    stats = alerts.webhooks.stats
    hooks = CounterMetricFamily(
        "irloc_webhook_bodies", "alert webhook bodies by outcome", labels=["outcome"]
    )
    for outcome, n in (
        ("delivered", stats.delivered),
        ("failed", stats.failed),
        ("dropped", stats.dropped),
        ("held_back", alerts.webhook_held),
    ):
        hooks.add_metric([outcome], n)
    yield hooks
    yield _counter("irloc_webhook_retries", "alert webhook tries repeated", stats.retries)


def reliability_metrics(s: SiteServices, state: State | None) -> Iterator[Metric]:
    """Everything above."""
    yield from edge_metrics(state)
    yield from storage_metrics(s)
    yield from site_metrics(s, state)
