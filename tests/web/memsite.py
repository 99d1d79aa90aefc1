"""A small in-memory `ViewerSite` for the viewer's unit tests: true landmark positions, a map
that may differ from them, radios not in the map (found by "discovery"), robots standing
still, LEDs, and camera views computed from the truth with `predict_pixels` (no image
rendering)."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from commissioning.candidates import new_radio_candidates
from commissioning.types import MapLandmark
from commissioning.wizard import (
    Cancel,
    Confirm,
    IdentificationWizard,
    SaveLandmark,
    Skip,
    Start,
    SwitchAnyway,
    WizardEvent,
    WizardStatus,
)
from live.cells import CellsReplaced
from live.facades import BatteryStatus
from live.survey.service import SurveyStatus
from localizer.camera import CameraModel, predict_pixels
from localizer.events import PoseEstimate
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera
from store.zones import PoseHistory, ZoneStore
from web.services import CameraView, Candidate, EventLine, LandmarkState, RobotState


class MemSite:
    def __init__(
        self,
        truth: dict[int, tuple[float, float, float]],
        poses: dict[str, tuple[float, float, float]],
    ) -> None:
        self.truth = {k: np.array(v, dtype=float) for k, v in truth.items()}
        self.map = {k: LandmarkState(k, *v) for k, v in truth.items()}
        self.radios: dict[str, np.ndarray] = {}  # address -> true position, not in the map
        self.radio_lit: set[str] = set()
        self.dead: frozenset[int] = frozenset()  # flat batteries: dark, their radio silent
        self.poses = poses
        self.camera: CameraModel = wide_angle_camera("pinhole")
        self._lit = frozenset(truth)
        self._lit_at = 0
        self.audit: list[tuple[str, str, int, LandmarkState | None, LandmarkState | None]] = []
        self.led_log: list[frozenset[int]] = []
        self.relocalized: list[str] = []
        self.held = False
        self.stored_cameras: list[tuple[str, str]] = []
        self.lock = threading.Lock()
        self.wizard = IdentificationWizard()  # driven by the tests (no LEDs switched here)
        self.survey = SurveyStatus("idle")  # the tests set its estimate
        self.zone_store: ZoneStore | None = None  # real stores on a SQLite file, when set
        self.history_store: PoseHistory | None = None
        self.cells: list[tuple[int, str]] = []

    # -- reads -----------------------------------------------------------------------------
    def landmarks(self) -> list[LandmarkState]:
        with self.lock:
            return sorted(self.map.values(), key=lambda lm: lm.id)

    def _visible_lit(self, name: str) -> list[int]:
        x, y, th = self.poses[name]
        ids = sorted(i for i in self._lit if i in self.truth)
        if not ids:
            return []
        p = np.array([self.truth[i] for i in ids])
        _, ok = predict_pixels(self.camera, T_world_body_from_pose(x, y, th), p)
        return [i for i, v in zip(ids, ok, strict=True) if v]

    def robots(self) -> list[RobotState]:
        now = time.monotonic_ns()
        out = []
        for name, (x, y, th) in self.poses.items():
            used = self._visible_lit(name)
            fixed = len(used) >= 2
            pose = PoseEstimate(now, x, y, th, np.diag([1e-4, 4e-4, 1e-4]), "landmark", tuple(used))
            last_fix = now if fixed else self._lit_at
            out.append(RobotState(name, self.camera, pose, "landmark" if fixed else
                                  "dead_reckoning", last_fix, now))  # fmt: skip
        return out

    def lit(self) -> frozenset[int]:
        return self._lit

    def events(self, limit: int) -> list[EventLine]:
        return [
            EventLine("2026-01-01T00:00:00Z", "map_changed", f"{a} {act} {i}")
            for a, act, i, _, _ in self.audit
        ][::-1][:limit]

    def camera_view(self, robot: str) -> CameraView | None:
        x, y, th = self.poses[robot]
        ids = sorted(i for i in self._lit if i in self.truth)
        lit = [self.truth[i] for i in ids] + [self.radios[a] for a in sorted(self.radio_lit)]
        p = np.array(lit).reshape(-1, 3)
        px, ok = predict_pixels(self.camera, T_world_body_from_pose(x, y, th), p)
        img = np.zeros((self.camera.height, self.camera.width), np.uint8)
        return CameraView(time.monotonic_ns(), img, px[ok])

    def map_history(self) -> None:
        return None

    def map_proposals(self) -> None:
        return None

    def floorplan(self) -> None:
        return None

    def recordings(self) -> None:
        return None

    def zones(self) -> ZoneStore | None:
        return self.zone_store

    def pose_history(self) -> PoseHistory | None:
        return self.history_store

    def floor_shown(self) -> str | None:
        return None

    def ceiling_height(self) -> float:
        return 2.5

    def floors(self) -> list[tuple[str, str]]:
        return [("0", "Floor 0")]  # one floor: the viewer shows no floor selector

    def show_floor(self, floor: str | None) -> None:
        return None

    def elsewhere(self) -> list[tuple[str, str]]:
        return []

    # -- actions -----------------------------------------------------------------------------
    def replace_cells(self, landmark_id: int, *, actor: str) -> CellsReplaced:
        if landmark_id not in self.map:
            raise KeyError(f"no landmark {landmark_id}")
        self.cells.append((landmark_id, actor))
        with self.lock:
            self.map[landmark_id] = replace(self.map[landmark_id], supply_mv=3150, percent=100.0,
                                            days_left=None)  # fmt: skip
        return CellsReplaced(BatteryStatus(landmark_id, 3150, 100.0, None, []), True)

    def relocalize(self, robot: str, *, actor: str) -> None:
        self.relocalized.append(robot)

    def store_camera(self, robot: str, camera: CameraModel, *, actor: str) -> None:
        with self.lock:
            self.camera = camera
            self.stored_cameras.append((robot, actor))

    def set_leds(self, lit: frozenset[int], *, actor: str) -> frozenset[int]:
        self._lit = frozenset(lit) - self.dead
        self._lit_at = time.monotonic_ns()
        self.led_log.append(frozenset(lit))
        return frozenset(self.dead)

    def add_landmark(
        self,
        landmark_id: int,
        x: float,
        y: float,
        z: float,
        *,
        actor: str,
        radio: str | None = None,
    ) -> LandmarkState:
        with self.lock:
            if landmark_id in self.map:
                raise ValueError(f"landmark {landmark_id} exists")
            lm = self.map[landmark_id] = LandmarkState(landmark_id, x, y, z, radio=radio)
            if radio is not None and radio in self.radios:  # a landmark now: the site switches it
                self.truth[landmark_id] = self.radios.pop(radio)
                if radio in self.radio_lit:
                    self.radio_lit.discard(radio)
                    self._lit = self._lit | {landmark_id}
            self.audit.append((actor, "create", landmark_id, None, lm))
            return lm

    def update_landmark(self, landmark_id: int, *, actor: str, **fields: Any) -> LandmarkState:
        with self.lock:
            old = self.map[landmark_id]
            if old.locked and any(fields.get(k) is not None for k in "xyz"):
                raise ValueError(f"landmark {landmark_id} is locked (surveyed)")
            lm = replace(old, **{k: v for k, v in fields.items() if v is not None})
            self.map[landmark_id] = lm
            self.audit.append((actor, "update", landmark_id, old, lm))
            return lm

    def delete_landmark(self, landmark_id: int, *, actor: str) -> None:
        with self.lock:
            old = self.map.pop(landmark_id)
            self.audit.append((actor, "delete", landmark_id, old, None))

    def to_identify(self, *, discover: bool = False) -> list[Candidate]:
        out = [Candidate(i, None, "doubted") for i, lm in sorted(self.map.items())
               if not lm.locked and lm.doubted]  # fmt: skip
        if discover:
            found = [(a, f"LM{a[-4:]}") for a in self.radios]
            out += new_radio_candidates(found, set(self.map))
        return out

    # -- the wizard: its own pure one, fed directly (no LEDs switched here) -----------------
    def _wizard_feed(self, event: WizardEvent) -> None:
        for out in self.wizard.handle(event):
            if isinstance(out, SaveLandmark):
                c, (x, y, z) = out.candidate, out.position
                self.update_landmark(c.landmark_id, actor="wizard", x=x, y=y, z=z)

    def wizard_status(self) -> WizardStatus:
        return self.wizard.status()

    def wizard_start(self, robot: str, queue: Sequence[Candidate], *, actor: str) -> None:
        lms = {i: MapLandmark(i, lm.x, lm.y, lm.z, lm.locked) for i, lm in self.map.items()}
        self._wizard_feed(Start(0, robot, self.camera, tuple(queue), lms, 2.5, tuple(self.poses)))

    def wizard_confirm(
        self,
        *,
        actor: str,
        position: tuple[float, float, float] | None = None,
        accept_far: bool = False,
    ) -> None:
        self._wizard_feed(Confirm(1, position, accept_far))

    def wizard_skip(self, *, actor: str) -> None:
        self._wizard_feed(Skip(1))

    def wizard_switch_anyway(self, *, actor: str) -> None:
        self._wizard_feed(SwitchAnyway(1))

    def wizard_cancel(self, *, actor: str) -> None:
        self._wizard_feed(Cancel(1))

    # -- the survey: a status the tests set; accepting writes its proposals ------------------
    def survey_status(self) -> SurveyStatus:
        return self.survey

    def survey_start(self, robot: str, *, actor: str) -> None:
        if robot not in self.poses:
            raise KeyError(f"unknown robot {robot!r}")
        self.survey = SurveyStatus("driving", robot)

    def survey_stop(self, *, actor: str) -> None:
        self.survey = replace(self.survey, state="solving")

    def survey_cancel(self, *, actor: str) -> None:
        self.survey = SurveyStatus("idle")

    def survey_accept(self, landmark_ids: Sequence[int] | None, *, actor: str) -> None:
        props = {p.landmark_id: p for p in self.survey.proposals}
        ids = [i for i, p in props.items() if not p.flags] if landmark_ids is None else landmark_ids
        missing = sorted(set(ids) - set(props))
        if missing:
            raise ValueError(f"landmarks: {missing} not surveyed")
        for i in ids:
            self.update_landmark(i, actor=actor, x=props[i].x, y=props[i].y, z=props[i].z)
        self.survey = replace(self.survey, accepted=(*self.survey.accepted, *ids))


def grid_site(*, doubted: dict[int, tuple[float, float]] | None = None) -> MemSite:
    """A 4x3 grid of landmarks 1 m apart at 2.5 m; robots r1 at (1.5, 1, 0.3) and r2."""
    truth = {
        10 + 4 * j + i: (float(i), float(j), 2.5 + 0.01 * i) for j in range(3) for i in range(4)
    }
    site = MemSite(truth, {"r1": (1.5, 1.0, 0.3), "r2": (0.5, 0.2, -2.0)})
    for lid, (dx, dy) in (doubted or {}).items():
        lm = site.map[lid]
        site.map[lid] = replace(lm, x=lm.x + dx, y=lm.y + dy, doubted=True)
    return site
