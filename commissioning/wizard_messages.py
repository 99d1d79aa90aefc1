"""The identification wizard's messages: the events it handles, the outputs it returns and
the status it reports (`commissioning.wizard.IdentificationWizard`). Plain data."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

from commissioning.measuring import Plausibility
from commissioning.types import Candidate, MapLandmark
from localizer.camera import CameraModel
from localizer.events import PoseEstimate
from localizer.types import FloatArray

Phase = Literal["idle", "waiting", "measuring", "done", "cancelled"]


# -- events in ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Start:
    """Begin with `robot`'s camera on `queue`.

    Attributes:
        landmarks: the map (ID -> landmark); ceiling_z: height of a new radio's LED, metres.
        robots: the robots running now (the chosen one must be among them).
    """

    t_ns: int
    robot: str
    camera: CameraModel
    queue: tuple[Candidate, ...]
    landmarks: Mapping[int, MapLandmark]
    ceiling_z: float
    robots: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class PoseSeen:
    """Any robot's estimate for one of its frames."""

    robot: str
    pose: PoseEstimate

    @property
    def t_ns(self) -> int:
        return self.pose.t_ns


@dataclass(frozen=True, eq=False)
class FrameSeen:
    """The chosen robot's frame: its spots (col, row), shape (N, 2), and its estimate for it."""

    robot: str
    pose: PoseEstimate
    pixels: FloatArray

    @property
    def t_ns(self) -> int:
        return self.pose.t_ns


@dataclass(frozen=True)
class LedsSeen:
    """A confirmed LED state: `lit` from `t_ns` on; `changing`: being switched."""

    t_ns: int
    lit: frozenset[int]
    changing: frozenset[int] = frozenset()


@dataclass(frozen=True)
class RadioSwitched:
    """A new radio acknowledged (or failed, `error`) switching its LED."""

    t_ns: int
    address: str
    on: bool
    error: str = ""


@dataclass(frozen=True)
class Tick:
    t_ns: int


@dataclass(frozen=True)
class Confirm:
    """Save the measurement, or `position` (typed by hand; x, y, z metres); `accept_far`
    confirms a measurement flagged far from the map."""

    t_ns: int
    position: tuple[float, float, float] | None = None
    accept_far: bool = False


@dataclass(frozen=True)
class Skip:
    t_ns: int


@dataclass(frozen=True)
class SwitchAnyway:
    """Darken the landmark even though a robot would lose its fix."""

    t_ns: int


@dataclass(frozen=True)
class Cancel:
    t_ns: int


WizardEvent = (
    Start
    | PoseSeen
    | FrameSeen
    | LedsSeen
    | RadioSwitched
    | Tick
    | Confirm
    | Skip
    | SwitchAnyway
    | Cancel
)


# -- outputs --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SwitchLandmark:
    """Darken landmark `landmark_id` alone (`on=False`: every other LED stays as it is), or
    give it back (`on=True`)."""

    landmark_id: int
    on: bool


@dataclass(frozen=True)
class SwitchRadio:
    """Switch a new radio's LED (not a landmark of the map yet); answer with
    `RadioSwitched`."""

    address: str
    on: bool


@dataclass(frozen=True)
class SaveLandmark:
    """Store the position: move landmark `candidate.landmark_id`, or create it with the new
    radio's address."""

    candidate: Candidate
    position: tuple[float, float, float]


@dataclass(frozen=True)
class Finished:
    phase: Literal["done", "cancelled"]
    saved: tuple[int, ...]
    skipped: tuple[int, ...]


WizardOutput = SwitchLandmark | SwitchRadio | SaveLandmark | Finished


@dataclass(frozen=True)
class Measurement:
    """The wizard's current proposal.

    Attributes:
        position: world frame, metres; samples: how many agree; spread_m: their spread, m.
        plausibility: against the map (`far` needs `Confirm(accept_far=True)`).
        pixel: where the target's spot was in the latest lit frame (col, row).
        frame_t_ns: that frame's time.
    """

    position: tuple[float, float, float]
    samples: int
    spread_m: float
    plausibility: Plausibility
    pixel: tuple[float, float] | None
    frame_t_ns: int


@dataclass(frozen=True)
class WizardStatus:
    """Where the wizard stands (what the REST API and the viewer show)."""

    phase: Phase
    robot: str
    index: int
    total: int
    candidate: Candidate | None
    prompt: str
    measurement: Measurement | None
    can_confirm: bool
    needs_accept_far: bool
    waiting_for: tuple[str, ...]
    saved: tuple[int, ...]
    skipped: tuple[int, ...]
