"""What a hostile or broken client on the broker can do to the site, bounded (docs/fleet.md).

The broker's ACL is the lock; this is the site server's own check behind it, one rule a
message kind, each breach a `fleet_intrusion` event (the first time, per agent where it
names one):
- agents: only admitted ones (names or patterns in `mqtt_agents`, else any up to
  `mqtt_max_agents`) are registered;
- LED requests: served when the agents are admitted by name, or when the server logs in to
  the broker (its ACL then vouches for who wrote what), never on an open broker without a
  list;
- poses: one outside the site (the map's extent and `SITE_MARGIN_M` around it) is dropped
  and counted;
- the map: one on the map topic that this server did not publish is counted (the bridge,
  `live.mqtt_bridge`, publishes the site's again at once).
"""

from __future__ import annotations

import fnmatch
import math

from fleet.payloads import PoseMessage
from live.events import EmitEvent
from store.models import LandmarkPublic

SITE_MARGIN_M = 50.0
"""Poses farther than this outside the map's extent are dropped."""
MAX_ABS_XY_M = 10_000.0
"""Without a map, poses farther than this from the origin are dropped."""


class FleetGuard:
    """The bridge's checks of what agents and other clients send (see the module docstring).

    Args:
        admitted: names or fnmatch patterns of the agents admitted (`mqtt_agents`); empty:
            any, up to `max_agents`.
        max_agents: the most agents the site registers (`mqtt_max_agents`).
        trust_logins: the server logs in to the broker, whose ACL vouches for who wrote
            what (LED requests are then served without a list).
        landmarks: the map whose extent bounds the poses (`set_map` replaces it).
        emit: where breaches are reported.

    Attributes:
        refused_agents, poses_outside, led_requests_refused, foreign_maps: what was refused
            or dropped so far.
    """

    def __init__(
        self,
        *,
        admitted: tuple[str, ...],
        max_agents: int,
        trust_logins: bool,
        landmarks: list[LandmarkPublic],
        emit: EmitEvent,
    ) -> None:
        self.admitted = admitted
        self.max_agents = max_agents
        self.trust_logins = trust_logins
        self._emit = emit
        self._bounds = map_extent(landmarks)
        self.refused_agents: set[str] = set()
        self.poses_outside = 0
        self._outside_told: set[str] = set()
        self.led_requests_refused = 0
        self._led_refusal_told: set[str] = set()
        self.foreign_maps = 0

    def set_map(self, landmarks: list[LandmarkPublic]) -> None:
        """Bound the poses by a new map's extent."""
        self._bounds = map_extent(landmarks)

    def refusal(self, robot: str, agents: int) -> str | None:
        """Why a new agent may not join a site that has `agents` agents (None: it may)."""
        if self.admitted and not any(fnmatch.fnmatchcase(robot, p) for p in self.admitted):
            return "not among the admitted agents (setting mqtt_agents)"
        if agents >= self.max_agents:
            return f"the site has its {self.max_agents} agents (setting mqtt_max_agents)"
        return None

    def refuse(self, robot: str, reason: str) -> None:
        """An agent was not registered (`refusal`): an event the first time."""
        if robot not in self.refused_agents:
            self.refused_agents.add(robot)
            self._emit(
                "fleet_intrusion",
                f"agent {robot} refused: {reason}",
                robot=robot,
                data={"what": "agent_refused"},
            )

    def inside_site(self, robot: str, msg: PoseMessage) -> bool:
        """Whether a pose is on the site (the map's extent and `SITE_MARGIN_M` around it);
        one outside is counted (an event the first time for each agent)."""
        if msg.x is None or msg.y is None:
            return True
        box = self._bounds
        if box is not None:
            x0, y0, x1, y1 = box
            m = SITE_MARGIN_M
            if (
                x0 - m <= msg.x <= x1 + m
                and y0 - m <= msg.y <= y1 + m
                and math.isfinite(msg.theta if msg.theta is not None else 0.0)
            ):
                return True
        elif abs(msg.x) <= MAX_ABS_XY_M and abs(msg.y) <= MAX_ABS_XY_M:
            return True
        self.poses_outside += 1
        if robot not in self._outside_told:
            self._outside_told.add(robot)
            self._emit(
                "fleet_intrusion",
                f"agent {robot}: a pose outside the site (x {msg.x:.4g}, y {msg.y:.4g} m) "
                "dropped; such poses are dropped and counted",
                robot=robot,
                data={"what": "pose_outside", "x": msg.x, "y": msg.y},
            )
        return False

    def serves_led_requests(self, robot: str) -> bool:
        """Whether a registered agent's LED requests are served; one refused is counted
        (an event the first time for each agent)."""
        if self.admitted or self.trust_logins:
            return True
        # an open broker and no list: anyone could claim to be this agent
        self.led_requests_refused += 1
        if robot not in self._led_refusal_told:
            self._led_refusal_told.add(robot)
            self._emit(
                "fleet_intrusion",
                f"agent {robot}: its LED requests are not served: the broker is open (no "
                "login) and no agent is admitted (setting mqtt_agents, docs/fleet.md)",
                robot=robot,
                data={"what": "led_request_refused"},
            )
        return False

    def foreign_map(self, topic: str) -> None:
        """A map this server did not publish appeared on `topic`: counted, an event the
        first time and every hundredth."""
        self.foreign_maps += 1
        if self.foreign_maps == 1 or self.foreign_maps % 100 == 0:
            self._emit(
                "fleet_intrusion",
                f"a map not published by this server appeared on {topic} "
                f"({self.foreign_maps} so far): the site's map was published again; "
                "restrict the broker with irloc's ACL (docs/fleet.md)",
                robot=None,
                data={"what": "foreign_map", "count": self.foreign_maps},
            )


def map_extent(landmarks: list[LandmarkPublic]) -> tuple[float, float, float, float] | None:
    """(x min, y min, x max, y max) of the map, metres; None when it is empty."""
    if not landmarks:
        return None
    xs, ys = [lm.x for lm in landmarks], [lm.y for lm in landmarks]
    return min(xs), min(ys), max(xs), max(ys)
