"""Who may do what in the viewer: the same roles as the REST API (`server.auth`).

viewer: sees everything, changes nothing. operator: also relocalizes robots (and switches
LEDs through the API). admin: also edits the map and runs the identification wizard (which
saves landmark positions), as the API requires admin for map changes.
"""

from __future__ import annotations

from dataclasses import dataclass

ROLE_RANK: dict[str, int] = {"viewer": 0, "operator": 1, "admin": 2}
TICKET_PARAM = "irloc_ticket"
"""The query parameter of viser's WebSocket URL carrying the proxy's one-time ticket."""


def check_role(role: str) -> str:
    """The role, or ValueError naming it."""
    if role not in ROLE_RANK:
        raise ValueError(f"unknown role {role!r}; one of {sorted(ROLE_RANK)}")
    return role


@dataclass(frozen=True)
class Session:
    """One browser connected to the viewer.

    Attributes:
        role: "viewer", "operator" or "admin" (from the API key the proxy checked).
        actor: how the audit log names this user, e.g. "viewer:key:3".
    """

    role: str
    actor: str

    def __post_init__(self) -> None:
        check_role(self.role)

    def allows(self, role: str) -> bool:
        """Whether this session's role is `role` or higher."""
        return ROLE_RANK[self.role] >= ROLE_RANK[check_role(role)]

    @property
    def can_operate(self) -> bool:
        return self.allows("operator")

    @property
    def can_commission(self) -> bool:
        return self.allows("admin")


ANONYMOUS = Session("viewer", "viewer:anonymous")
"""A browser that reached viser without the proxy's ticket (loopback only): read-only."""
