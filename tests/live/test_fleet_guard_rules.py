"""The MQTT bridge's guard, on its own: which agents join, which poses and LED requests are
taken, what is counted and which breaches become `fleet_intrusion` events (once each).
The same rules against a real broker: tests/fleet/test_fleet_guard.py."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from fleet.payloads import PoseMessage
from live.events import EventKind
from live.fleet_guard import SITE_MARGIN_M, FleetGuard, map_extent
from store.models import LandmarkPublic

T0 = datetime(2026, 1, 1, tzinfo=UTC)


class Events:
    def __init__(self) -> None:
        self.seen: list[tuple[EventKind, str, str | None, dict[str, Any] | None]] = []

    def __call__(
        self,
        kind: EventKind,
        message: str,
        *,
        robot: str | None = None,
        data: dict[str, Any] | None = None,
    ) -> None:
        self.seen.append((kind, message, robot, data))


def _landmark(i: int, x: float, y: float) -> LandmarkPublic:
    return LandmarkPublic(id=i, x=x, y=y, z=2.5, created_at=T0, updated_at=T0)


def _guard(
    events: Events, *, admitted: tuple[str, ...] = (), trust_logins: bool = False
) -> FleetGuard:
    lms = [_landmark(1, 0.0, 0.0), _landmark(2, 10.0, 4.0)]
    return FleetGuard(
        admitted=admitted, max_agents=2, trust_logins=trust_logins, landmarks=lms, emit=events
    )


def _pose(x: float, y: float) -> PoseMessage:
    return PoseMessage(seq=1, t_ns=1, wall_ns=1, mode="landmark", x=x, y=y, theta=0.0)


def test_admission_by_pattern_and_by_the_sites_agent_count() -> None:
    guard = _guard(Events(), admitted=("amr-*", "dock"))
    assert guard.refusal("amr-7", agents=0) is None
    assert guard.refusal("dock", agents=0) is None
    assert "mqtt_agents" in (guard.refusal("intruder", agents=0) or "")
    assert "mqtt_max_agents" in (guard.refusal("amr-8", agents=2) or "")


def test_a_refused_agent_is_one_event_however_often_it_knocks() -> None:
    events = Events()
    guard = _guard(events)
    for _ in range(3):
        guard.refuse("x1", "not admitted")
    assert guard.refused_agents == {"x1"}
    assert [(k, r, d) for k, _, r, d in events.seen] == [
        ("fleet_intrusion", "x1", {"what": "agent_refused"})
    ]


def test_poses_beyond_the_margin_around_the_map_are_dropped_counted_and_told_once() -> None:
    events = Events()
    guard = _guard(events)
    assert map_extent([_landmark(1, 0.0, 0.0), _landmark(2, 10.0, 4.0)]) == (0.0, 0.0, 10.0, 4.0)
    assert guard.inside_site("a1", _pose(10.0 + SITE_MARGIN_M, -SITE_MARGIN_M))
    assert not guard.inside_site("a1", _pose(10.0 + SITE_MARGIN_M + 0.01, 0.0))
    assert not guard.inside_site("a1", _pose(-1e6, 0.0))
    assert guard.poses_outside == 2 and len(events.seen) == 1
    assert events.seen[0][3] == {"what": "pose_outside", "x": 60.01, "y": 0.0}
    guard.set_map([_landmark(3, 100.0, 0.0)])  # the map moved: so does the site
    assert guard.inside_site("a1", _pose(140.0, 0.0))


def test_led_requests_on_an_open_broker_without_a_list_are_refused() -> None:
    events = Events()
    open_broker = _guard(events)
    assert not open_broker.serves_led_requests("a1")
    assert not open_broker.serves_led_requests("a1")
    assert open_broker.led_requests_refused == 2 and len(events.seen) == 1
    assert _guard(Events(), admitted=("a1",)).serves_led_requests("a1")
    assert _guard(Events(), trust_logins=True).serves_led_requests("a1")


def test_foreign_maps_are_counted_and_told_the_first_time_and_every_hundredth() -> None:
    events = Events()
    guard = _guard(events)
    for _ in range(200):
        guard.foreign_map("irloc/default/map")
    assert guard.foreign_maps == 200
    assert [d["count"] for _, _, _, d in events.seen if d is not None] == [1, 100, 200]
