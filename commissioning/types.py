"""The values the commissioning logic takes and gives (docs/commissioning.md)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Candidate:
    """Something the identification wizard can identify.

    Attributes:
        landmark_id: the landmark (for a new radio: the ID it gets when saved).
        radio: for a new radio from discovery (not in the map): its 64-bit address.
        reason: why it is offered, for people ("doubted: ...", "new radio ...").
    """

    landmark_id: int
    radio: str | None = None
    reason: str = ""

    @property
    def is_new(self) -> bool:
        """A radio from discovery, not yet a landmark of the map."""
        return self.radio is not None


@dataclass(frozen=True)
class MapLandmark:
    """A landmark of the map as commissioning needs it: ID, LED position (world frame,
    metres) and whether it is surveyed (locked: commissioning does not move it)."""

    id: int
    x: float
    y: float
    z: float
    locked: bool = False
