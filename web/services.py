"""What the viewer needs from the site: the `ViewerSite` protocol and the snapshots it returns.

The viewer never touches the database, radio or localizers directly: it reads snapshots and
calls the same data layer as the REST API through an object of this protocol
(`web.adapter.SiteAdapter` wraps the server's `SiteServices`). Tests drive the viewer through
the same protocol.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from commissioning.types import Candidate
from commissioning.wizard import WizardStatus
from live.cells import CellsReplaced
from live.facades import Recordings
from live.survey.service import SurveyStatus
from live.upkeep_service import MapUpkeepService
from localizer.camera import CameraModel
from localizer.events import PoseEstimate
from store.floorplan import FloorPlanStore
from store.landmarks import MapRepository
from store.zones import PoseHistory, ZoneStore

__all__ = [
    "CameraView",
    "Candidate",
    "EventLine",
    "LandmarkState",
    "RobotState",
    "ViewerSite",
]


@dataclass(frozen=True)
class LandmarkState:
    """One landmark as shown.

    Attributes:
        id: landmark ID; x, y, z: LED position in the world frame, metres.
        locked: surveyed, not to be moved by commissioning.
        radio: 64-bit radio address (16 hex digits) or None.
        supply_mv: latest battery reading, millivolts, None when never read.
        percent: rough charge 0-100 (the server's `BatteryStatus.percent`), None when unknown.
        days_left: estimated days until the cut-off voltage, None when unknown.
        reachable: False once the radio stopped answering.
        doubted: localized robots expected it in view but rarely used it (`commissioning.doubt`).
        lit: its LED is lit now; lit_reason: why the LED schedule lights it (None: dark,
            or every LED lit without a schedule).
        duty: share of the time it was lit since the site started.
        model_days: days its cells last at that duty from the measured voltage (the energy
            model, `live.leds.status`), None when never read.
        low: flagged: its LED dims within a week at that duty, or is dim already.
        sigma_m: the map's 1-sigma uncertainty of its position, metres (None: not known).
    """

    id: int
    x: float
    y: float
    z: float
    locked: bool = False
    radio: str | None = None
    supply_mv: int | None = None
    percent: float | None = None
    days_left: float | None = None
    reachable: bool = True
    doubted: bool = False
    lit: bool = False
    lit_reason: str | None = None
    duty: float | None = None
    model_days: float | None = None
    low: bool = False
    sigma_m: float | None = None


@dataclass(frozen=True, eq=False)
class RobotState:
    """One robot as shown.

    Attributes:
        name: robot name.
        camera: its camera model with mounting.
        pose: the latest estimate, None before the first fix.
        mode: the localizer's mode now.
        last_fix_t_ns: time of the latest landmark fix, None before one.
        now_ns: the site clock when this snapshot was taken.
        reason_text: why its latest pose is no landmark fix ("" when it is one).
        quality: the latest pose's 0-1 quality (None: not known).
    """

    name: str
    camera: CameraModel
    pose: PoseEstimate | None
    mode: str
    last_fix_t_ns: int | None
    now_ns: int
    reason_text: str = ""
    quality: float | None = None


@dataclass(frozen=True)
class EventLine:
    """A line of the event list (low battery, landmark unreachable, robot lost, map changed).

    Attributes:
        when: local time with its zone, e.g. "2026-12-01 21:04:05 CET"
            (`web.panels.monitor.local_time_text`); kind: the event kind; message: for
            people.
    """

    when: str
    kind: str
    message: str


@dataclass(frozen=True, eq=False)
class CameraView:
    """A robot's latest frame and the spots detected in it.

    Attributes:
        t_ns: when it was taken.
        image: 8-bit grayscale, shape (H, W).
        spots: spot centroids (col, row), shape (N, 2).
    """

    t_ns: int
    image: npt.NDArray[np.uint8]
    spots: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))


class ViewerSite(Protocol):
    """The site as the viewer sees it. Every method is thread-safe and returns promptly."""

    def landmarks(self) -> list[LandmarkState]:
        """Every landmark of the map, with battery and radio state."""
        ...

    def robots(self) -> list[RobotState]:
        """Every robot's latest state."""
        ...

    def lit(self) -> frozenset[int]:
        """IDs of the landmarks whose LED is lit now."""
        ...

    def events(self, limit: int) -> list[EventLine]:
        """The most recent events, newest first."""
        ...

    def camera_view(self, robot: str) -> CameraView | None:
        """The robot's latest frame with its detections; None when it has none."""
        ...

    def map_history(self) -> MapRepository | None:
        """The stored map with its undo/redo history (None: no database behind the site)."""
        ...

    def map_proposals(self) -> MapUpkeepService | None:
        """The map upkeep's proposals from the robots' views (None: no upkeep runs)."""
        ...

    def floorplan(self) -> FloorPlanStore | None:
        """The shown floor's plan image and its placement (None: the site keeps none)."""
        ...

    def zones(self) -> ZoneStore | None:
        """The site's zones, as `/api/v1/zones` (None: the site keeps none)."""
        ...

    def pose_history(self) -> PoseHistory | None:
        """The robots' kept poses, as `/api/v1/history` (None: the site keeps none)."""
        ...

    def recordings(self) -> Recordings | None:
        """The robots' recordings: start, stop, list, zip, delete (None: none kept)."""
        ...

    def ceiling_height(self) -> float:
        """The nominal ceiling (LED) height, metres."""
        ...

    def floors(self) -> list[tuple[str, str]]:
        """(id, name) of every floor, lowest level first."""
        ...

    def show_floor(self, floor: str | None) -> None:
        """Show one floor's landmarks and robots (`landmarks`, `robots`); None: every floor."""
        ...

    def elsewhere(self) -> list[tuple[str, str]]:
        """(robot, floor) of the robots on a floor not shown, by name."""
        ...

    def floor_shown(self) -> str | None:
        """The floor shown (`show_floor`; None: every floor)."""
        ...

    # -- actions (role checked by the caller); ValueError/KeyError carry the reason --------
    def relocalize(self, robot: str, *, actor: str) -> None: ...

    def set_leds(self, lit: frozenset[int], *, actor: str) -> frozenset[int]:
        """Light exactly `lit`, darken the others (waits for the radio).

        Returns:
            the landmarks whose radio did not answer (their LED state is unknown; the
            others were switched).
        """
        ...

    def add_landmark(
        self,
        landmark_id: int,
        x: float,
        y: float,
        z: float,
        *,
        actor: str,
        radio: str | None = None,
    ) -> LandmarkState: ...

    def update_landmark(
        self,
        landmark_id: int,
        *,
        actor: str,
        x: float | None = None,
        y: float | None = None,
        z: float | None = None,
        locked: bool | None = None,
    ) -> LandmarkState: ...

    def delete_landmark(self, landmark_id: int, *, actor: str) -> None: ...

    def replace_cells(self, landmark_id: int, *, actor: str) -> CellsReplaced:
        """Fresh cells in a landmark: its battery estimate starts over (`live.cells`, as
        `POST /landmarks/{id}/cells-replaced`; waits for the radio's reading)."""
        ...

    def store_camera(self, robot: str, camera: CameraModel, *, actor: str) -> None:
        """Replace the robot's camera (lens and mounting) and restart its localizer."""
        ...

    def to_identify(self, *, discover: bool = False) -> list[Candidate]:
        """What to identify: doubted landmarks and, with `discover`, the radios a discovery
        finds that are not in the map (it waits for the radio; ValueError when it fails)."""
        ...

    # -- the site's identification wizard (`commissioning.wizard`, run by the server) -------
    def wizard_status(self) -> WizardStatus:
        """Where the wizard stands now."""
        ...

    def wizard_start(self, robot: str, queue: Sequence[Candidate], *, actor: str) -> None:
        """Start identifying `queue` with `robot`'s camera (ValueError: why not)."""
        ...

    def wizard_confirm(
        self,
        *,
        actor: str,
        position: tuple[float, float, float] | None = None,
        accept_far: bool = False,
    ) -> None:
        """Save the agreed measurement (or `position`); a far one needs `accept_far`."""
        ...

    def wizard_skip(self, *, actor: str) -> None: ...

    def wizard_switch_anyway(self, *, actor: str) -> None: ...

    def wizard_cancel(self, *, actor: str) -> None: ...

    # -- the site's live survey (`live.survey.service.LiveSurvey`, run by the server) ------
    def survey_status(self) -> SurveyStatus:
        """Where the survey is: its live estimate, route, or final proposals."""
        ...

    def survey_start(self, robot: str, *, actor: str) -> None:
        """Start surveying with `robot` (ValueError/KeyError/RuntimeError: why not)."""
        ...

    def survey_stop(self, *, actor: str) -> None:
        """End the drive and solve it."""
        ...

    def survey_cancel(self, *, actor: str) -> None:
        """Drop the survey; nothing is written."""
        ...

    def survey_accept(self, landmark_ids: Sequence[int] | None, *, actor: str) -> None:
        """Write these landmarks' estimates into the map (None: every unflagged one)."""
        ...
