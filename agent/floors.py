"""Which floor's map an agent localizes on (sans-I/O): it keeps every floor's map it
received (`<site>/maps/<floor>`, and the default floor's on `<site>/map`), localizes on the
floor the site tells it (`agents/<name>/floor`), else on the one it starts on, else on the
floor of its first map; a floor change (or a pose to start from) makes it identify again
once it holds that floor's map. On a site with several floors it withholds its poses while
its view does not fit its floor's map (`fleet.floor_fit`: it changed floors untold, or
rides a lift) until it is told its floor or fits its map again. `agent.core.AgentCore`
asks it what to do with each message.
"""

from __future__ import annotations

import logging

from fleet.floor_fit import FloorFit
from fleet.payloads import FloorMessage, MapMessage
from localizer.events import NoPose, PoseEstimate

log = logging.getLogger(__name__)
Near = tuple[float, float, float]


class Floors:
    """One agent's floors.

    Args:
        name: the robot's name (for the log).
        floor: the floor it starts on when it knows (None: the floor of its first map).
    """

    def __init__(self, name: str, floor: str | None) -> None:
        self.name = name
        self.wanted: str | None = floor
        """The floor to localize on (told, or started on); None: not known yet."""
        self._maps: dict[str, MapMessage] = {}
        self._assignment_n: int | None = None
        self._reidentify: tuple[bool, Near | None] = (False, None)
        self.fit = FloorFit()

    def on_map(self, msg: MapMessage, held: str | None) -> bool:
        """Keep a floor's map; True when the agent must take it now (`held`: the floor
        whose map it holds, None before the first)."""
        self._maps[msg.floor] = msg
        return msg.floor == (self.wanted or held or msg.floor)

    def on_floor(self, msg: FloorMessage, held: str | None) -> MapMessage | None:
        """The site has the robot on `msg.floor`: the map to take now (None: not here yet,
        or the retained copy of an assignment already taken). A floor other than the one
        it localizes on, or a pose to start from (`near`), makes it identify again when
        it takes that floor's map (`reidentify`)."""
        if msg.n == self._assignment_n:
            return None  # the retained copy seen again after a reconnect
        self._assignment_n = msg.n
        if msg.floor != (held or self.wanted) or msg.near is not None:
            self._reidentify = (True, msg.near)
        self.wanted = msg.floor
        self.fit.known()
        log.info("%s: on floor %s (near %s)", self.name, msg.floor, msg.near)
        return self._maps.get(msg.floor)

    def reidentify(self) -> tuple[bool, Near | None]:
        """Whether to forget the pose (and where to identify again) with the map taken
        now; asked once per map taken."""
        wanted, self._reidentify = self._reidentify, (False, None)
        return wanted

    def withhold(self, out: PoseEstimate | NoPose) -> bool:
        """Take one frame's localizer output; True when its floor is unknown (its pose
        withheld). A site with one floor (one map received) has no other floor to be on."""
        return len(self._maps) > 1 and self.fit.observe(out)

    def waiting(self, held: str | None) -> bool:
        """Told a floor whose map it does not hold yet: no pose of the old floor goes out."""
        return self.wanted is not None and held != self.wanted
