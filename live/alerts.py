"""Alerts: the rules that turn the site's conditions into raised and resolved alerts (pure).

A *condition* is something wrong now (`Condition`: a robot is lost, a landmark's radio does
not answer, a camera is silent ...), keyed by its kind and subject (`robot_lost:r1`). The
`AlertBook` is fed what holds at each check (`update(now_s, wall, holding, unsure)`) and
answers with `Notification`s, at most one per change:

- **raised** once a condition has held continuously for `raise_after_s`, and not sooner
  than `min_interval_s` after the same alert was last raised (a flapping condition raises
  at most once per interval: no storm);
- **resolved** once it has been absent for `clear_after_s` (a short gap keeps it active);
- conditions that cannot be judged now (`unsure`: the landmarks' radios while the radio link
  is down, a disconnected agent's camera) neither progress nor resolve.

No clock and no I/O: the caller passes the monotonic time (intervals) and the wall time
(what the messages say), and delivers the notifications (`live.alert_service`).
"""

from __future__ import annotations

import json
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass, field, replace
from datetime import datetime
from typing import Any, Literal, get_args

AlertKind = Literal[
    "robot_lost",
    "robot_offline",
    "camera_stale",
    "odometry_stale",
    "landmark_unreachable",
    "landmark_low_battery",
    "radio_down",
]
"""What an alert is about (docs/alerts.md)."""
ALERT_KINDS: tuple[str, ...] = get_args(AlertKind)
Severity = Literal["critical", "warning"]
SEVERITY: Mapping[str, Severity] = {
    "robot_lost": "critical",
    "robot_offline": "critical",
    "camera_stale": "critical",
    "odometry_stale": "warning",
    "landmark_unreachable": "warning",
    "landmark_low_battery": "warning",
    "radio_down": "critical",
}
AlertState = Literal["raised", "resolved"]


@dataclass(frozen=True)
class AlertConfig:
    """Attributes:
    raise_after_s: a condition must hold this long, without a gap, before it is raised.
    clear_after_s: a raised alert is resolved once its condition has been absent this long.
    min_interval_s: the same alert (kind and subject) is raised at most once per interval.
    """

    raise_after_s: float = 3.0
    clear_after_s: float = 10.0
    min_interval_s: float = 60.0


@dataclass(frozen=True)
class Condition:
    """Something wrong now. `subject`: the robot's name, the landmark's id, `radio`."""

    kind: AlertKind
    subject: str
    message: str
    robot: str | None = None
    landmark_id: int | None = None
    data: Mapping[str, Any] = field(default_factory=dict)

    @property
    def key(self) -> str:
        return f"{self.kind}:{self.subject}"


@dataclass(frozen=True)
class Alert:
    """A raised alert (active while `resolved_at` is None)."""

    condition: Condition
    raised_at: datetime
    resolved_at: datetime | None = None

    @property
    def key(self) -> str:
        return self.condition.key

    def to_dict(self) -> dict[str, Any]:
        c = self.condition
        return {
            "key": c.key,
            "kind": c.kind,
            "subject": c.subject,
            "severity": SEVERITY[c.kind],
            "active": self.resolved_at is None,
            "message": c.message,
            "robot": c.robot,
            "landmark_id": c.landmark_id,
            "data": dict(c.data),
            "raised_at": self.raised_at.isoformat(),
            "resolved_at": None if self.resolved_at is None else self.resolved_at.isoformat(),
        }


@dataclass(frozen=True)
class Notification:
    """One change of one alert, as every channel delivers it (`to_dict`)."""

    seq: int
    state: AlertState
    alert: Alert

    @property
    def message(self) -> str:
        what = self.alert.condition.message
        return what if self.state == "raised" else f"resolved: {what}"

    def to_dict(self, site: str) -> dict[str, Any]:
        """The alert with `state`, `seq` (increasing per server run), `site` and `text` (a
        line for people: chat webhooks show it as it is)."""
        state = self.state.upper()
        return {
            **self.alert.to_dict(),
            "state": self.state,
            "seq": self.seq,
            "site": site,
            "text": f"[irloc {site}] {state} {SEVERITY[self.alert.condition.kind]}: "
            f"{self.alert.condition.message}",
        }

    def json(self, site: str) -> bytes:
        return json.dumps(self.to_dict(site), separators=(",", ":")).encode()


@dataclass
class _Track:
    """What the book knows of one key."""

    since: float | None = None  # when the condition started holding (None: not holding)
    last_seen: float = 0.0
    condition: Condition | None = None
    alert: Alert | None = None
    last_raised: float | None = None


def _is_unsure(cond: Condition, unsure: Collection[tuple[str, str | None]]) -> bool:
    return (cond.kind, cond.subject) in unsure or (cond.kind, None) in unsure


class AlertBook:
    """The alerts' state machine (see the module)."""

    def __init__(self, config: AlertConfig | None = None) -> None:
        self.config = config or AlertConfig()
        self._tracks: dict[str, _Track] = {}
        self._seq = 0

    def active(self) -> list[Alert]:
        """The raised alerts not yet resolved, oldest first."""
        alerts = [t.alert for t in self._tracks.values() if t.alert is not None]
        return sorted(alerts, key=lambda a: (a.raised_at, a.key))

    def update(
        self,
        now_s: float,
        wall: datetime,
        holding: Iterable[Condition],
        unsure: Collection[tuple[str, str | None]] = (),
    ) -> list[Notification]:
        """One check: `holding` are the conditions true now; `unsure` lists (kind, subject)
        or (kind, None: every subject) that cannot be judged now."""
        cfg = self.config
        out: list[Notification] = []
        seen: set[str] = set()
        for cond in holding:
            seen.add(cond.key)
            track = self._tracks.setdefault(cond.key, _Track())
            if track.since is None:
                track.since = now_s
            track.last_seen, track.condition = now_s, cond
            if track.alert is not None:  # still raised: the latest details, no message
                track.alert = replace(track.alert, condition=cond)
                continue
            held = now_s - track.since >= cfg.raise_after_s
            spaced = track.last_raised is None or now_s - track.last_raised >= cfg.min_interval_s
            if held and spaced:
                track.alert = Alert(cond, wall)
                track.last_raised = now_s
                out.append(self._note("raised", track.alert))
        for key, track in list(self._tracks.items()):
            if key in seen or track.condition is None:
                continue
            if _is_unsure(track.condition, unsure):
                track.last_seen = now_s  # its absence is not known: nothing changes
                continue
            track.since = None
            if track.alert is not None and now_s - track.last_seen >= cfg.clear_after_s:
                done = replace(track.alert, resolved_at=wall)
                track.alert = None
                out.append(self._note("resolved", done))
            if track.alert is None and (
                track.last_raised is None or now_s - track.last_raised >= cfg.min_interval_s
            ):
                del self._tracks[key]  # nothing left to remember
        return out

    def _note(self, state: AlertState, alert: Alert) -> Notification:
        self._seq += 1
        return Notification(self._seq, state, alert)
