"""Keeping the map true: robots at work refine the landmark positions slowly, and a landmark
whose evidence says it moved beyond its stated uncertainty is proposed to staff.

`MapUpkeep` takes, per localized frame with a confident fix, the frame's spots and the
robot's estimate (`observe`). Each frame's information on the landmarks it saw, its pose
eliminated (`survey.upkeep_frame`), is added to one information matrix over all landmarks: a
recursive, information-form estimate of every landmark's displacement from the map, with the
map itself as the prior (each landmark `map_sigma_m` per axis, or what an accepted proposal
said). The map's frame is the prior's: the robots' views fix landmarks relative to each
other, never the whole map's position or heading.

`proposals()` tests each landmark against its prior (Baarda's data snooping): its estimated
displacement d and the covariance of that displacement under "it did not move",
S = Sigma_prior - C_post + sigma_floor^2 I, give d^T S^-1 d, chi-square with 3 degrees of
freedom. Once a landmark with at least `min_views` views exceeds `chi2_threshold`, its prior
is dropped (it moved: it must not drag its neighbours), the rest are solved again and the
next is tested. Moved landmarks are proposed where the views put them; unmoved ones whose
uncertainty the views shrank below `refine_ratio` of their prior are proposed as refined.
Nothing is applied: the caller shows the proposals to staff, and tells `accepted` or
`rejected` what they decided. Pure: numpy in, values out; no clock.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from localizer.camera import CameraModel
from localizer.events import PoseEstimate
from localizer.noise_model import PixelNoiseConfig, PixelNoiseModel
from localizer.types import FloatArray
from survey.upkeep_frame import INTRINSICS, frame_evidence, match_spots

ProposalKind = Literal["moved", "refined"]


@dataclass(frozen=True)
class UpkeepConfig:
    """Which frames count and when a change is proposed.

    Attributes:
        map_sigma_m: the map's stated 1-sigma uncertainty per axis, metres (a survey's);
            the prior of every landmark the map stores no sigma for until a proposal for it
            is accepted.
        floor_sigma_m: systematic error the views cannot average away (the cameras'
            calibration, the other landmarks' survey), per axis, metres: added to every
            test and to every proposed sigma.
        chi2_threshold: a landmark moved when its test statistic (chi-square, 3 degrees of
            freedom) exceeds this; 30.7 is the 1e-6 tail: a site of 100 landmarks tested
            every second for a year stays clear of false proposals mostly.
        min_views: views a landmark needs before it can be proposed as moved.
        min_views_refined: ... as refined.
        refine_ratio: refined when its posterior sigma is at most this share of its prior.
        min_shift_m: a refinement smaller than this is not worth a proposal, metres.
        gate_m: a spot is matched to a landmark within this distance on the ceiling, metres
            (farther moves are for doubt detection and the wizard, docs/commissioning.md).
        isolation_m: ... when no other spot or landmark is this close to either, metres.
        max_sigma_m: a frame counts when the robot's 1-sigma position error is at most this.
        min_used: ... when its localizer used at least this many landmarks in its fix.
        settle_s: ... when its fixes lasted this long since it last had no pose, seconds.
        view_spacing_m: a robot's frames count once it moved this far since its last
            counted frame, metres (neighbouring frames see through the same errors) ...
        view_turn_rad: ... or turned this much, radians.
        free_sigma_m: prior kept on a moved landmark (practically none), metres.
        focal_rel: prior of each robot's camera focal errors (relative; fu and fv apart),
            estimated with the map: what a calibration leaves
            (`localizer.noise_model.PixelNoiseConfig`) ...
        principal_px: ... and of its principal point, pixels.
    """

    map_sigma_m: float = 0.003
    floor_sigma_m: float = 0.001
    chi2_threshold: float = 30.7
    min_views: int = 10
    min_views_refined: int = 30
    refine_ratio: float = 0.8
    min_shift_m: float = 0.0005
    gate_m: float = 0.15
    isolation_m: float = 0.3
    max_sigma_m: float = 0.05
    min_used: int = 2
    settle_s: float = 2.0
    view_spacing_m: float = 0.2
    view_turn_rad: float = 0.2
    free_sigma_m: float = 1.0
    focal_rel: float = 0.002
    principal_px: float = 0.6

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            low = 0.0 if f.name == "settle_s" else math.ulp(0.0)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= low):
                what = "a number >= 0" if low == 0 else "a positive number"
                raise ValueError(f"UpkeepConfig.{f.name} must be {what}, got {v!r}")


@dataclass(frozen=True)
class MapProposal:
    """A change of one landmark's position the robots' views call for (not applied).

    Attributes:
        landmark_id: the landmark.
        kind: "moved" (beyond its stated uncertainty) or "refined" (within it, known better).
        old: the map's position (x, y, z), metres; proposed: the views' position.
        sigma_m: 1-sigma uncertainty of `proposed` (largest semi-axis), metres.
        views: frames that saw it (the evidence count).
        statistic: its chi-square test statistic against the map (3 degrees of freedom).
        shift_m: distance between `old` and `proposed`, metres.
    """

    landmark_id: int
    kind: ProposalKind
    old: tuple[float, float, float]
    proposed: tuple[float, float, float]
    sigma_m: float
    views: int
    statistic: float
    shift_m: float


class MapUpkeep:
    """Every landmark's slowly refined position and whether it moved (module docstring)."""

    def __init__(self, config: UpkeepConfig | None = None) -> None:
        self.config = config or UpkeepConfig()
        self._ids: list[int] = []
        self._slot: dict[int, int] = {}
        self._robots: list[str] = []
        self._where = np.zeros((0, 3))
        self._sigma = np.zeros(0)
        self._info = np.zeros((0, 0))
        self._vec = np.zeros(0)
        self._views = np.zeros(0, dtype=np.int64)
        self._noise: dict[int, tuple[CameraModel, PixelNoiseModel]] = {}
        self._last: dict[str, tuple[float, float, float]] = {}
        self._fix_since: dict[str, int] = {}
        self.frames = 0

    # -- the map --------------------------------------------------------------------------------
    def set_map(
        self, positions: Mapping[int, npt.ArrayLike], sigmas: Mapping[int, float] | None = None
    ) -> None:
        """The map's landmark positions (id -> (3,)), metres, and the 1-sigma uncertainty the
        map stores for some (id -> metres; a landmark surveyed to 1 mm weighs more than a
        taped one). A landmark moved in the map keeps its evidence, re-centred on its new
        position, and its prior is its stored sigma, else `map_sigma_m` (`accepted` then
        sets its own); new ones start with none."""
        new = {int(k): np.asarray(v, dtype=np.float64).reshape(3) for k, v in positions.items()}
        ids = sorted(new)
        n, r = len(ids), INTRINSICS * len(self._robots)
        info, vec = np.zeros((3 * n + r, 3 * n + r)), np.zeros(3 * n + r)
        sigma = np.full(n, self.config.map_sigma_m)
        views = np.zeros(n, dtype=np.int64)
        keep = [(i, self._slot[lid]) for i, lid in enumerate(ids) if lid in self._slot]
        n_old = len(self._ids)
        a = np.array([3 * i + c for i, _ in keep for c in range(3)] + [3 * n + k for k in range(r)])
        b = np.array(
            [3 * j + c for _, j in keep for c in range(3)] + [3 * n_old + k for k in range(r)]
        )
        if len(a):
            old_info = self._info[np.ix_(b, b)]
            shift = np.concatenate([new[ids[i]] - self._where[j] for i, j in keep] + [np.zeros(r)])
            info[np.ix_(a, a)] = old_info
            vec[a] = self._vec[b] - old_info @ shift  # the same evidence about the new origin
        if keep:
            same = [(i, j) for i, j in keep if np.array_equal(new[ids[i]], self._where[j])]
            sigma[[i for i, _ in same]] = self._sigma[[j for _, j in same]]
            views[[i for i, _ in keep]] = self._views[[j for _, j in keep]]
        for i, lid in enumerate(ids):
            if sigmas and lid in sigmas and sigmas[lid] > 0:
                sigma[i] = max(float(sigmas[lid]), self.config.floor_sigma_m)
        self._ids, self._slot = ids, {lid: i for i, lid in enumerate(ids)}
        self._where = np.array([new[i] for i in ids]).reshape(n, 3)
        self._info, self._vec, self._sigma, self._views = info, vec, sigma, views

    def _robot_rows(self, robot: str) -> list[int]:
        """The rows of a robot's camera intrinsics (added at its first counted frame)."""
        if robot not in self._robots:
            self._robots.append(robot)
            self._info = np.pad(self._info, ((0, INTRINSICS), (0, INTRINSICS)))
            self._vec = np.pad(self._vec, (0, INTRINSICS))
        first = 3 * len(self._ids) + INTRINSICS * self._robots.index(robot)
        return list(range(first, first + INTRINSICS))

    def accepted(self, landmark_id: int, sigma_m: float) -> None:
        """Staff accepted a proposal (the map now holds it: call `set_map` first): the
        landmark's prior becomes `sigma_m` and its evidence, now in the map, is dropped."""
        self._forget(landmark_id)
        self._sigma[self._slot[landmark_id]] = sigma_m

    def rejected(self, landmark_id: int) -> None:
        """Staff rejected a proposal: the landmark's evidence is dropped, to be gathered
        afresh (a landmark that really moved is proposed again after `min_views`)."""
        self._forget(landmark_id)

    def _forget(self, landmark_id: int) -> None:
        if landmark_id not in self._slot:
            raise KeyError(f"landmark {landmark_id} is not in the map")
        i = self._slot[landmark_id]
        s = slice(3 * i, 3 * i + 3)
        self._info[s, :] = 0.0
        self._info[:, s] = 0.0
        self._vec[s] = 0.0
        self._views[i] = 0

    # -- frames ---------------------------------------------------------------------------------
    def wants(self, robot: str, pose: PoseEstimate) -> bool:
        """Whether a robot's estimate for a frame would count (landmark mode, settled,
        confident, moved on since its last counted frame): fetch the frame's spots only
        then. Keeps track of when the robot last had no pose."""
        cfg = self.config
        if pose.mode != "landmark":
            if pose.mode in ("identifying", "lost"):
                self._fix_since.pop(robot, None)
            return False
        since = self._fix_since.setdefault(robot, pose.t_ns)
        cov = np.asarray(pose.covariance, dtype=np.float64)
        if (
            pose.t_ns - since < cfg.settle_s * 1e9
            or len(pose.landmark_ids) < cfg.min_used
            or not math.sqrt(max(0.0, float(cov[0, 0] + cov[1, 1]))) <= cfg.max_sigma_m
            or not self._ids
        ):
            return False
        last = self._last.get(robot)
        return last is None or (
            math.hypot(pose.x - last[0], pose.y - last[1]) >= cfg.view_spacing_m
            or abs(math.remainder(pose.theta - last[2], math.tau)) >= cfg.view_turn_rad
        )

    def observe(
        self, robot: str, camera: CameraModel, pose: PoseEstimate, pixels: npt.ArrayLike
    ) -> int:
        """One robot's estimate for a frame and that frame's spots (N, 2), raw pixels.
        Returns how many landmarks the frame gave evidence on (0: it did not count)."""
        cfg = self.config
        if not self.wants(robot, pose):
            return 0
        here = (float(pose.x), float(pose.y), float(pose.theta))
        candidates = [
            self._slot[i] for i in {*pose.landmark_ids, *pose.expected_ids} if i in self._slot
        ]
        candidates.sort()
        if len(candidates) < 2:
            return 0
        pos = self._where[candidates]
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        pairs = match_spots(camera, here, px, pos, gate_m=cfg.gate_m, isolation_m=cfg.isolation_m)
        rows = [candidates[j] for j, _ in pairs]
        used = set(pose.landmark_ids)
        fit = [k for k, r in enumerate(rows) if self._ids[r] in used]
        noise = self._noise_model(camera)
        ev = frame_evidence(
            camera,
            here,
            px[[s for _, s in pairs]],
            self._where[rows],
            [self._ids[r] for r in rows],
            noise.sigma_px,
            fit_rows=fit,
        )
        if ev is None:
            return 0
        idx = np.array([3 * r + c for r in rows for c in range(3)] + self._robot_rows(robot))
        self._info[np.ix_(idx, idx)] += ev.information
        self._vec[idx] += ev.vector
        self._views[rows] += 1
        self._last[robot] = here
        self.frames += 1
        return len(rows)

    def _noise_model(self, camera: CameraModel) -> PixelNoiseModel:
        """The localizer's pixel noise for this camera, without the survey part (the
        landmarks' positions are the unknowns here) and not adapted."""
        hit = self._noise.get(id(camera))
        if hit is not None and hit[0] is camera:
            return hit[1]
        cfg = dataclasses.replace(PixelNoiseConfig(), survey_sigma_m=0.0, adapt=False)
        model = PixelNoiseModel(camera, cfg, 1.0)
        self._noise[id(camera)] = (camera, model)
        return model

    # -- estimates and proposals ----------------------------------------------------------------
    def landmarks_seen(self) -> int:
        """Landmarks with evidence since the map last changed them."""
        return int(np.count_nonzero(self._views))

    def views(self, landmark_id: int) -> int:
        """Frames that gave evidence on the landmark since the map last changed it."""
        return int(self._views[self._slot[landmark_id]])

    def estimate(self, free: frozenset[int] = frozenset()) -> tuple[FloatArray, FloatArray]:
        """Every landmark's posterior position (N, 3) and covariance (N, 3, 3), in the order
        of the sorted IDs; the landmarks in `free` without their prior."""
        pos, cov, _ = self._solve(free)
        return pos, cov

    def _solve(self, free: frozenset[int]) -> tuple[FloatArray, FloatArray, FloatArray]:
        n = len(self._ids)
        cfg = self.config
        camera = [cfg.focal_rel**2] * 2 + [cfg.principal_px**2] * 2
        prior_var = np.concatenate([np.repeat(self._sigma**2, 3), camera * len(self._robots)])
        for lid in free:
            i = self._slot[lid]
            prior_var[3 * i : 3 * i + 3] = self.config.free_sigma_m**2
        info = self._info + np.diag(1.0 / prior_var)
        chol = np.linalg.cholesky(info)
        C = np.linalg.inv(chol)
        C = C.T @ C
        delta = C @ self._vec
        blocks = np.array([C[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] for i in range(n)])
        return self._where + delta[: 3 * n].reshape(n, 3), blocks.reshape(n, 3, 3), prior_var

    def proposals(self) -> list[MapProposal]:
        """Landmarks that moved beyond their uncertainty, then refined ones (module
        docstring), by ID within each kind."""
        cfg = self.config
        if not self._ids:
            return []
        floor = cfg.floor_sigma_m**2 * np.eye(3)
        free: dict[int, float] = {}
        while True:
            pos, cov, prior_var = self._solve(frozenset(free))
            stats = self._statistics(pos, cov, prior_var, floor, free)
            if not stats:
                break
            lid, d2 = max(stats.items(), key=lambda kv: kv[1])
            if d2 <= cfg.chi2_threshold:
                break
            free[lid] = d2
        out = []
        for lid in sorted(free):
            out.append(self._proposal(lid, "moved", pos, cov, floor, free[lid]))
        stats = self._statistics(pos, cov, prior_var, floor, free, refined=True)
        for lid in sorted(stats):
            i = self._slot[lid]
            sigma = _largest_sigma(cov[i] + floor)
            shift = float(np.linalg.norm(pos[i] - self._where[i]))
            if sigma <= cfg.refine_ratio * self._sigma[i] and shift >= cfg.min_shift_m:
                out.append(self._proposal(lid, "refined", pos, cov, floor, stats[lid]))
        return out

    def _statistics(
        self,
        pos: FloatArray,
        cov: FloatArray,
        prior_var: FloatArray,
        floor: FloatArray,
        free: Mapping[int, float],
        *,
        refined: bool = False,
    ) -> dict[int, float]:
        """Each testable landmark's chi-square against its prior (enough views, not free)."""
        need = self.config.min_views_refined if refined else self.config.min_views
        out = {}
        for lid, i in self._slot.items():
            if lid in free or self._views[i] < need:
                continue
            d = pos[i] - self._where[i]
            S = np.diag(prior_var[3 * i : 3 * i + 3]) - cov[i] + floor
            out[lid] = float(d @ np.linalg.solve(S, d))
        return out

    def _proposal(
        self,
        lid: int,
        kind: ProposalKind,
        pos: FloatArray,
        cov: FloatArray,
        floor: FloatArray,
        statistic: float,
    ) -> MapProposal:
        i = self._slot[lid]
        old = tuple(float(v) for v in self._where[i])
        new = tuple(float(v) for v in pos[i])
        return MapProposal(
            lid,
            kind,
            (old[0], old[1], old[2]),
            (new[0], new[1], new[2]),
            _largest_sigma(cov[i] + floor),
            int(self._views[i]),
            statistic,
            float(np.linalg.norm(pos[i] - self._where[i])),
        )


def _largest_sigma(cov: FloatArray) -> float:
    """The largest semi-axis of a 1-sigma ellipsoid, metres."""
    return float(math.sqrt(max(0.0, float(np.linalg.eigvalsh(cov)[-1]))))
