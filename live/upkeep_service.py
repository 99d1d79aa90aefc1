"""Keeping the map true on the live site: the robots' frames refine the landmark positions
(`survey.upkeep`), and what they call for is proposed to staff, never applied by itself.

One task on the server's loop takes every pose update from the pose bus (as doubt detection
does, `live.commissioning_service`) and, on a worker thread, hands the estimates that would
count (`MapUpkeep.wants`: landmark mode, settled, confident, moved on since the robot's last
counted frame) to the estimator with their frame's spots (detected here from the runner's
recent frames, `RobotRunner.frame_at`, or as a remote robot sent them). Robots localized on
board (`irloc agent`) send the spots of a confident frame with its pose now and then
(`AgentConfig.spots_period_s`); the agent's runner keeps them for `frame_at`.

Accepting a proposal is an ordinary map edit through the map's data layer (`MapRepository`:
audited as "<actor> (map upkeep)", undoable); rejecting one drops that landmark's evidence
and is logged as a site event. Locked landmarks are proposed too, flagged: accepting every
proposal leaves them out, naming one accepts it. docs/map-upkeep.md.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from live.events import EventKind
from live.pose_pump import PosePump
from localizer.camera import CameraModel
from localizer.events import FrameObserved, PoseEstimate
from localizer.spots import DetectionConfig, detect_spots
from store.errors import ConflictError
from store.models import LandmarkPublic, LandmarkUpdate
from survey.upkeep import MapProposal, MapUpkeep, UpkeepConfig

if TYPE_CHECKING:  # the facades are handed in (live.services); typing only
    from live.facades import Robots
    from live.poses import PoseUpdate
    from store.landmarks import MapRepository

log = logging.getLogger(__name__)
ACTOR_SUFFIX = " (map upkeep)"
"""Appended to the staff member's name in the audit log of an accepted proposal."""


@dataclass(frozen=True)
class ProposalView:
    """A proposal as staff see it: the estimator's, and whether the landmark is locked."""

    proposal: MapProposal
    locked: bool


@dataclass(frozen=True)
class UpkeepStatus:
    """What the robots' views say about the map.

    Attributes:
        frames: frames that gave evidence since the site started.
        landmarks_seen: landmarks with evidence since the map last changed them.
        proposals: moved landmarks first, then refined ones.
    """

    frames: int
    landmarks_seen: int
    proposals: tuple[ProposalView, ...]


class MapUpkeepService:
    """The estimator fed by the pose bus, and staff's decisions on its proposals.

    Args:
        map, robots: the site's facades.
        config: the estimator's tuning; detection: spot detection on full frames.
        emit: logs a site event (kind, message), e.g. `EventHub.emit`; None: not logged.
        batch_s: pose updates are taken in batches at most this often, seconds.
    """

    def __init__(
        self,
        map: MapRepository,
        robots: Robots,
        *,
        config: UpkeepConfig | None = None,
        detection: DetectionConfig | None = None,
        emit: Callable[[EventKind, str], object] | None = None,
        batch_s: float = 0.1,
    ) -> None:
        self.map, self.robots = map, robots
        self.detection = detection or DetectionConfig()
        self.batch_s = batch_s
        self._emit = emit
        self._upkeep = MapUpkeep(config)
        self._lock = threading.RLock()
        self._pump = PosePump(robots, self.take, batch_s=batch_s, name="map upkeep")

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        """Subscribe to the map and the poses (on the server's loop)."""
        self._on_map(self.map.list())
        self.map.add_listener(self._on_map)
        self._pump.start()

    async def stop(self) -> None:
        self.map.remove_listener(self._on_map)
        await self._pump.stop()

    @property
    def failures(self) -> int:
        """Pose batches that failed (logged)."""
        return self._pump.failures

    # -- inputs ---------------------------------------------------------------------------------
    def _on_map(self, landmarks: list[LandmarkPublic]) -> None:
        with self._lock:
            self._upkeep.set_map(
                {lm.id: (lm.x, lm.y, lm.z) for lm in landmarks},
                {lm.id: lm.sigma_m for lm in landmarks if lm.sigma_m is not None},
            )

    def take(self, batch: Sequence[PoseUpdate]) -> int:
        """Pose updates from the bus: those that count, with their frames' spots, to the
        estimator. Returns how many frames gave evidence."""
        counted = 0
        for upd in batch:
            pose = upd.estimate()
            if pose is None:
                continue
            with self._lock:
                if not self._upkeep.wants(upd.robot, pose):
                    continue
            try:
                runner = self.robots.get(upd.robot)
            except KeyError:
                continue
            frame = runner.frame_at(upd.t_ns)
            if frame is None:
                continue
            if isinstance(frame, FrameObserved):
                pixels = detect_spots(frame.image, self.detection).pixels
            else:
                pixels = frame.pixels
            counted += self.observe(upd.robot, runner.camera, pose, np.asarray(pixels)) > 0
        return counted

    def observe(
        self, robot: str, camera: CameraModel, pose: PoseEstimate, pixels: npt.ArrayLike
    ) -> int:
        """One frame's spots (N, 2) with the robot's estimate for it (`MapUpkeep.observe`;
        what `take` does for the pose bus); returns how many landmarks it gave evidence on."""
        with self._lock:
            return self._upkeep.observe(robot, camera, pose, pixels)

    # -- proposals ------------------------------------------------------------------------------
    def status(self) -> UpkeepStatus:
        """The proposals now, each flagged when its landmark is locked."""
        locked = {lm.id for lm in self.map.list() if lm.locked}
        with self._lock:
            props = self._upkeep.proposals()
            frames, seen = self._upkeep.frames, self._upkeep.landmarks_seen()
        views = tuple(ProposalView(p, p.landmark_id in locked) for p in props)
        return UpkeepStatus(frames, seen, views)

    def _chosen(self, landmark_ids: Sequence[int] | None) -> list[ProposalView]:
        """The proposals of `landmark_ids` (None: every unlocked one); ConflictError naming
        the IDs without a proposal (now)."""
        views = self.status().proposals
        by_id = {v.proposal.landmark_id: v for v in views}
        if landmark_ids is None:
            return [v for v in views if not v.locked]
        missing = sorted({int(i) for i in landmark_ids} - set(by_id))
        if missing:
            have = ", ".join(str(i) for i in sorted(by_id)) or "none"
            raise ConflictError(
                f"landmarks: {', '.join(map(str, missing))} have no proposal "
                f"(proposals now: {have}); nothing was changed"
            )
        return [by_id[i] for i in dict.fromkeys(int(i) for i in landmark_ids)]

    def accept(self, landmark_ids: Sequence[int] | None, *, actor: str) -> list[int]:
        """Write the proposed positions of `landmark_ids` (None: every proposal of an unlocked
        landmark) into the map, audited and undoable; returns the IDs written. ConflictError
        (nothing written) when one has no proposal."""
        chosen = self._chosen(landmark_ids)
        done = []
        for v in chosen:
            p = v.proposal
            x, y, z = p.proposed
            evidence = {
                "source": "map upkeep",
                "kind": p.kind,
                "views": p.views,
                "chi2": round(p.statistic, 2),
            }
            self.map.update(
                p.landmark_id,
                LandmarkUpdate(x=x, y=y, z=z, sigma_m=p.sigma_m, evidence=evidence),
                actor=actor + ACTOR_SUFFIX,
            )
            with self._lock:  # the map's listener did this already, unless not started
                self._on_map(self.map.list())
                self._upkeep.accepted(p.landmark_id, p.sigma_m)
            done.append(p.landmark_id)
        return done

    def reject(self, landmark_ids: Sequence[int], *, actor: str) -> list[int]:
        """Drop the evidence behind the proposals of `landmark_ids` (the map is not changed);
        ConflictError (nothing dropped) when one has no proposal, ValueError when none is
        given."""
        if not landmark_ids:
            raise ValueError("landmarks: name at least one landmark whose proposal to reject")
        chosen = self._chosen(landmark_ids)
        done = []
        with self._lock:
            for v in chosen:
                self._upkeep.rejected(v.proposal.landmark_id)
                done.append(v.proposal.landmark_id)
        if self._emit is not None:
            ids = ", ".join(map(str, done))
            self._emit("map_proposal_rejected", f"{actor} rejected the map proposals of {ids}")
        return done
