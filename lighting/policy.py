"""Which landmarks to light: only those some robot sees now or will see soon, and of those a
few well-spread ones per robot rather than every one in view (pure logic, no clock, no I/O).

Per robot, `plan_leds`:
1. Without a usable pose the robot's neighbourhood is lit: while it identifies (no pose
   yet, or lost, even with a prior) every landmark, since a partly dark ceiling leaves a
   regular grid's shifted hypotheses unrefuted (a prior-guided hand-off then takes the
   wrong row); a robot in dead reckoning whose pose grew too uncertain gets every landmark
   within what its camera can see from anywhere it may be.
2. With a pose, its motion (velocity, or its route when known) is sampled from now to
   `horizon_s` ahead. At each sample the landmarks in view with a margin are found (the
   camera model's projection, the image shrunk by the pose uncertainty plus how far the robot
   can drive at its maximum speed while a command is on its way, `latency_s`). Each sample
   needs `per_robot` lit ones among them: those already chosen count; more are added greedily
   (a set cover), the landmark that serves the most samples still short first (few
   landmarks, each in view for long), then the best spread (far from the chosen ones in
   view: good geometry), then those lit already (no radio command), then the least worn
   (lit-seconds so far), then the nearest to the view's centre.
   A moving robot in dead reckoning (no fix from what is lit: an occlusion, a landmark
   whose spot is too faint at the edge) gets every landmark in its view lit until it fixes
   again. A robot parked for `parked_after_s` with a good pose needs nothing (its pose does not
   change while it stands; an idle site goes dark), unless what others need puts lit
   landmarks in its view: then it gets `per_robot` of its own there too (a localizer that
   predicts lit landmarks in view but matches fewer than two takes its observations for
   disagreeing with the map, and gets lost).
3. Everything chosen is lit; a landmark chosen less than `hold_s` ago stays lit (no
   flapping); the rest is darkened. While a robot identifies (or is lost), nothing is
   darkened and only what is needed is added: identification compares frames whose LED
   states differ in exactly the landmark it probes, so every other switch spoils its
   evidence, and a switch in flight makes the state of every frame meanwhile unknown.
   At most `max_switches` changes are made per plan (the radio's command budget): lights
   needed soonest first, then darkening.

Reasons (for the viewer's battery panel) name the robot and why: "view r1" (needed now),
"ahead r1" (within the horizon), "area r1" (no usable pose), "held", "pinned: <why>".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from lighting.camera_view import in_view, project_from_poses, view_reach_m, visible
from localizer.camera import CameraModel
from localizer.events import Mode
from localizer.types import FloatArray, IntArray


@dataclass(frozen=True)
class ScheduleConfig:
    """Tuning of the LED schedule.

    Attributes:
        per_robot: lit landmarks wanted in a robot's view at each moment (2 fix a pose; a
            third keeps it when one is occluded or leaves the view).
        horizon_s: how far ahead the robot's motion is followed, seconds (beyond the radio
            latency).
        sample_s: step of the motion samples, seconds.
        latency_s: worst time from a decision to the LED switching (radio wake-up latency
            plus the plan period), seconds.
        pose_sigma_k: the view's margin counts this many standard deviations of position.
        max_sigma_m: beyond this position standard deviation the pose is not used, metres.
        parked_after_s: a robot slower than `parked_speed_mps` for this long is parked,
            seconds.
        parked_speed_mps: see `parked_after_s`, m/s.
        hold_s: a landmark stays lit this long after it was last chosen, seconds.
        max_switches: LED changes per plan at most (the radio's command budget).
        spread_m: a landmark this far from the chosen ones counts as well spread, metres.
        wear_weight: how much wear (lit hours) counts against a landmark in metres of spread.
        ceiling_m: height of the landmarks above the floor for the view's scale, metres.
        centre_weight: how much a landmark's distance from the image centre (as a share of
            the half diagonal) counts against it in the cover (edge spots are faint and
            leave the view first).
        keep_seen: a lit landmark in a tracking robot's view now is not darkened until the
            robot has `per_robot` others in view that are confirmed lit and chosen (a robot
            whose old landmarks go dark while the new ones are still being switched, their
            state unknown for up to a sleep period with sleeping radios, has nothing to
            track and drifts into a wrong fix).
    """

    per_robot: int = 3
    horizon_s: float = 2.0
    sample_s: float = 0.25
    latency_s: float = 0.3
    pose_sigma_k: float = 2.0
    max_sigma_m: float = 0.5
    parked_after_s: float = 20.0
    parked_speed_mps: float = 0.02
    hold_s: float = 0.3
    max_switches: int = 40
    spread_m: float = 1.2
    wear_weight: float = 0.2
    ceiling_m: float = 2.5
    centre_weight: float = 0.4
    keep_seen: bool = True

    def __post_init__(self) -> None:
        if self.per_robot < 1 or self.sample_s <= 0 or self.horizon_s < 0:
            raise ValueError(
                "ScheduleConfig: per_robot >= 1, sample_s > 0, horizon_s >= 0, got "
                f"{self.per_robot}, {self.sample_s}, {self.horizon_s}"
            )


@dataclass(frozen=True, eq=False)
class RobotState:
    """What the scheduler knows of one robot at plan time.

    Attributes:
        name: the robot.
        camera: its camera (intrinsics and mounting).
        max_speed: m/s.
        mode: the localizer's mode.
        pose: (x, y, theta) of its last estimate, or None (never had one).
        covariance: of the pose, shape (3, 3), or None.
        pose_age_s: seconds since that estimate.
        v, omega: its speed (m/s) and turn rate (rad/s) now.
        still_s: how long it has been slower than `parked_speed_mps`, seconds.
        route: the points it will drive through next, (x, y) in metres, or empty.
    """

    name: str
    camera: CameraModel
    max_speed: float
    mode: Mode
    pose: tuple[float, float, float] | None
    covariance: FloatArray | None = None
    pose_age_s: float = 0.0
    v: float = 0.0
    omega: float = 0.0
    still_s: float = 0.0
    route: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class LedPlan:
    """The LEDs to light and why.

    Attributes:
        lit: the landmarks to light (all others dark).
        reasons: landmark ID -> why it is lit.
        wanted: what would be lit without the command budget.
        deferred: changes left for a later plan (budget).
        planned: chosen for a robot's later view, to be lit by a later plan (not before
            the command must leave: `latency_s` ahead of need).
    """

    lit: frozenset[int]
    reasons: dict[int, str] = field(default_factory=dict)
    wanted: frozenset[int] = frozenset()
    deferred: int = 0
    planned: frozenset[int] = frozenset()


def position_sigma(covariance: FloatArray | None) -> float:
    """Largest standard deviation of position, metres (inf without a covariance)."""
    if covariance is None:
        return math.inf
    c = np.asarray(covariance, dtype=np.float64)[:2, :2]
    return float(math.sqrt(max(float(np.linalg.eigvalsh(c).max()), 0.0)))


def motion_samples(
    robot: RobotState, config: ScheduleConfig
) -> list[tuple[float, tuple[float, float, float]]]:
    """(seconds ahead, pose) along the robot's predicted motion from now to the horizon:
    along its route when it has one (at its present speed, or half its maximum when
    stopped), else along the arc of its present (v, omega)."""
    if robot.pose is None:
        raise ValueError(f"motion_samples: robot {robot.name!r} has no pose")
    x, y, th = robot.pose
    total = config.latency_s + config.horizon_s
    n = max(math.ceil(total / config.sample_s), 1)
    out: list[tuple[float, tuple[float, float, float]]] = [(0.0, (x, y, th))]
    if robot.route:
        speed = abs(robot.v) if abs(robot.v) > config.parked_speed_mps else 0.5 * robot.max_speed
        pts = [(x, y), *robot.route]
        seg, px, py = 0, x, y
        for k in range(1, n + 1):
            left = speed * config.sample_s
            while left > 0 and seg < len(pts) - 1:
                tx, ty = pts[seg + 1]
                d = math.hypot(tx - px, ty - py)
                if d <= left:
                    px, py, left, seg = tx, ty, left - d, seg + 1
                    if d > 1e-9:
                        th = math.atan2(ty - pts[seg - 1][1], tx - pts[seg - 1][0])
                else:
                    th = math.atan2(ty - py, tx - px)
                    px, py, left = px + (tx - px) * left / d, py + (ty - py) * left / d, 0.0
            out.append((k * config.sample_s, (px, py, th)))
        return out
    for k in range(1, n + 1):
        t = k * config.sample_s
        if abs(robot.omega) < 1e-6:
            px, py, pth = x + robot.v * t * math.cos(th), y + robot.v * t * math.sin(th), th
        else:
            r = robot.v / robot.omega
            pth = th + robot.omega * t
            px = x + r * (math.sin(pth) - math.sin(th))
            py = y - r * (math.cos(pth) - math.cos(th))
        out.append((t, (px, py, pth)))
    return out


def _usable_pose(robot: RobotState, config: ScheduleConfig) -> bool:
    return (
        robot.pose is not None
        and robot.mode in ("landmark", "dead_reckoning")
        and position_sigma(robot.covariance) <= config.max_sigma_m
    )


def _neighbourhood(
    robot: RobotState, ids: Sequence[int], xy: FloatArray, config: ScheduleConfig
) -> list[int]:
    if robot.pose is None or robot.mode in ("identifying", "lost"):
        return list(ids)
    sigma = position_sigma(robot.covariance)
    sigma = 2.0 if not math.isfinite(sigma) else sigma
    radius = (
        view_reach_m(robot.camera, config.ceiling_m)
        + config.pose_sigma_k * sigma
        + robot.max_speed * config.latency_s
    )
    d = np.hypot(xy[:, 0] - robot.pose[0], xy[:, 1] - robot.pose[1])
    return [ids[int(k)] for k in np.flatnonzero(d <= radius)]


def _choose(
    candidates: IntArray,
    centre_px: FloatArray,
    chosen: set[int],
    need: int,
    ids: Sequence[int],
    xy: FloatArray,
    lit_now: frozenset[int],
    wear_h: Mapping[int, float],
    config: ScheduleConfig,
) -> list[int]:
    """Greedy: add landmarks (row indices `candidates`) until `need` are chosen among them."""
    have = [int(k) for k in candidates if ids[k] in chosen]
    added: list[int] = []
    pool = [int(k) for k in candidates if ids[k] not in chosen]
    while len(have) + len(added) < need and pool:
        picked = have + added
        best, best_score = -1, -math.inf
        for k in pool:
            if picked:
                d = float(np.min(np.hypot(xy[picked, 0] - xy[k, 0], xy[picked, 1] - xy[k, 1])))
                spread = min(d, config.spread_m)
            else:
                spread = config.spread_m
            score = (
                spread
                + (0.3 if ids[k] in lit_now else 0.0)
                - config.wear_weight * wear_h.get(ids[k], 0.0)
                - 1e-4 * float(centre_px[k])
            )
            if score > best_score:
                best, best_score = k, score
        pool.remove(best)
        added.append(best)
    return [ids[k] for k in added]


def _cover(
    camera: CameraModel,
    views: list[tuple[float, IntArray, FloatArray]],
    chosen: set[int],
    ids: Sequence[int],
    xy: FloatArray,
    keep: frozenset[int],
    wear_h: Mapping[int, float],
    config: ScheduleConfig,
) -> list[tuple[int, float]]:
    """Greedy cover of the motion samples (t, candidate rows, centre distances): landmarks to
    add, with the first sample time each serves, so that each sample has `per_robot`."""
    have = {k for k in range(len(ids)) if ids[k] in chosen}
    need = [min(config.per_robot, len(cand)) for _, cand, _ in views]
    half_diag = 0.5 * math.hypot(camera.width, camera.height)
    sets = [set(int(k) for k in cand) for _, cand, _ in views]
    added: list[tuple[int, float]] = []
    while True:
        short = [j for j, s in enumerate(sets) if len(s & have) < need[j]]
        if not short:
            return added
        pool: dict[int, int] = {}
        for j in short:
            for k in sets[j] - have:
                pool[k] = pool.get(k, 0) + 1
        if not pool:
            return added
        j0 = short[0]
        near = [k for k in have if k in sets[j0]]
        best, best_score = -1, -math.inf
        for k, serves in pool.items():
            if near:
                d = float(np.min(np.hypot(xy[near, 0] - xy[k, 0], xy[near, 1] - xy[k, 1])))
                spread = min(d, config.spread_m) / config.spread_m
            else:
                spread = 1.0
            centre = float(views[j0][2][k]) / half_diag if k in sets[j0] else 1.0
            score = (
                serves
                + 2.0 * spread
                + (0.5 if ids[k] in keep else 0.0)
                - config.wear_weight * wear_h.get(ids[k], 0.0)
                - config.centre_weight * min(centre, 1.0)
            )
            if score > best_score:
                best, best_score = k, score
        have.add(best)
        first = next(t for (t, _, _), s in zip(views, sets, strict=True) if best in s)
        added.append((ids[best], first))


def plan_leds(
    robots: Sequence[RobotState],
    landmark_ids: Sequence[int],
    positions: FloatArray,
    *,
    lit_now: frozenset[int],
    last_chosen_s: Mapping[int, float],
    wear_h: Mapping[int, float],
    pinned: Mapping[int, str] | None = None,
    config: ScheduleConfig | None = None,
    confirmed: frozenset[int] | None = None,
) -> LedPlan:
    """The LEDs to light now (see the module docstring).

    Args:
        robots: every robot's state.
        landmark_ids: the controlled landmarks; positions: theirs, shape (N, 3).
        lit_now: the landmarks lit now (confirmed).
        last_chosen_s: per landmark, seconds since a plan last chose it (absent: never).
        wear_h: per landmark, hours lit so far (wear to spread).
        pinned: landmarks others need lit (identification, the survey) -> why.
        confirmed: the landmarks confirmed lit and not being switched (None: `lit_now`).
    """
    cfg = config or ScheduleConfig()
    ids = [int(i) for i in landmark_ids]
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    xy = P[:, :2]
    reasons: dict[int, str] = {}
    urgency: dict[int, float] = {}

    def want(lid: int, why: str, t: float) -> None:
        if lid not in reasons:
            reasons[lid] = why
        urgency[lid] = min(urgency.get(lid, math.inf), t)

    for lid, why in (pinned or {}).items():
        if lid in ids:
            want(lid, f"pinned: {why}", 0.0)
    parked: list[RobotState] = []
    planned: set[int] = set()
    keep = lit_now | frozenset(k for k, s in last_chosen_s.items() if s < cfg.hold_s)
    for robot in sorted(robots, key=lambda r: r.name):
        if not _usable_pose(robot, cfg):
            for lid in _neighbourhood(robot, ids, xy, cfg):
                want(lid, f"area {robot.name}", 0.0)
            continue
        if robot.still_s >= cfg.parked_after_s and abs(robot.omega) < 0.05:
            parked.append(robot)
            continue
        sigma = position_sigma(robot.covariance)
        margin = cfg.pose_sigma_k * sigma + robot.max_speed * cfg.latency_s
        if robot.mode == "dead_reckoning":  # no fix from what is lit: light all it sees
            seen, _ = in_view(robot.camera, robot.pose, P, 0.0, cfg.ceiling_m)  # type: ignore[arg-type]
            for k in np.flatnonzero(seen):
                want(ids[int(k)], f"boost {robot.name} (no fix)", 0.0)
        views = []
        samples = motion_samples(robot, cfg)  # one projection serves every sample
        px, valid = project_from_poses(robot.camera, [pose for _, pose in samples], P)
        robust, centre_robust = visible(robot.camera, px, valid, margin, cfg.ceiling_m)
        seen, centre_seen = visible(robot.camera, px, valid, 0.0, cfg.ceiling_m)
        for j, (t, _) in enumerate(samples):
            cand, centre = np.flatnonzero(robust[j]), centre_robust[j]
            if len(cand) < cfg.per_robot:  # sparse ceiling: any landmark in view will do
                cand, centre = np.flatnonzero(seen[j]), centre_seen[j]
            views.append((t, cand, centre))
        cover = _cover(robot.camera, views, set(reasons) | planned, ids, xy, keep, wear_h, cfg)
        for lid, t in cover:
            if t <= cfg.latency_s + cfg.sample_s:  # its command must leave now
                want(lid, f"{'view' if t <= cfg.sample_s else 'ahead'} {robot.name}", t)
            else:  # chosen, lit by a later plan (it keeps the choice: `keep`)
                planned.add(lid)
        for t, cand, _ in views:
            for k in cand:
                if ids[k] in reasons:
                    urgency[ids[k]] = min(urgency.get(ids[k], math.inf), t)
    for robot in parked:  # dark, unless something lit is in its view: then a proper set
        assert robot.pose is not None
        seen, _ = in_view(robot.camera, robot.pose, P, 0.0, cfg.ceiling_m)
        if not any(ids[k] in reasons for k in np.flatnonzero(seen)):
            continue
        margin = cfg.pose_sigma_k * position_sigma(robot.covariance)
        robust, centre = in_view(robot.camera, robot.pose, P, margin, cfg.ceiling_m)
        cand = np.flatnonzero(robust)
        cand = cand[np.argsort(centre[cand], kind="stable")]
        for lid in _choose(
            cand, centre, set(reasons), cfg.per_robot, ids, xy, lit_now, wear_h, cfg
        ):
            want(lid, f"view {robot.name} (parked, others lit in its view)", 0.0)
    if cfg.keep_seen:
        sure = lit_now if confirmed is None else confirmed
        for robot in robots:
            if robot.pose is None or robot.mode not in ("landmark", "dead_reckoning"):
                continue
            if any(robot is p for p in parked):  # standing: its pose does not need them
                continue
            seen, _ = in_view(robot.camera, robot.pose, P, 0.0, cfg.ceiling_m)
            seen_ids = [ids[int(k)] for k in np.flatnonzero(seen)]
            usable = [i for i in seen_ids if i in sure and i in reasons]
            if len(usable) >= cfg.per_robot:
                continue
            for lid in seen_ids:
                if lid in lit_now and lid not in reasons:
                    reasons[lid] = f"seen {robot.name} (until its new ones are lit)"
    wanted = set(reasons)
    identifying = any(r.mode in ("identifying", "lost") for r in robots)
    for lid in lit_now:
        recent = last_chosen_s.get(lid, math.inf) < cfg.hold_s
        if lid not in wanted and lid in ids and (recent or identifying):
            reasons[lid] = "held" if recent else "held: a robot identifies"
    target = set(reasons)
    on = sorted(target - lit_now, key=lambda i: (urgency.get(i, math.inf), i))
    off = sorted(lit_now - target)
    budget = cfg.max_switches
    lit = set(lit_now) & set(ids)
    for lid in on[:budget]:
        lit.add(lid)
    for lid in off[: max(budget - len(on), 0)]:
        lit.discard(lid)
    deferred = max(len(on) - budget, 0) + max(len(off) - max(budget - len(on), 0), 0)
    for lid in lit:
        reasons.setdefault(lid, "darkening deferred (radio budget)")
    return LedPlan(
        frozenset(lit),
        {i: reasons[i] for i in sorted(lit)},
        frozenset(wanted),
        deferred,
        frozenset(planned - wanted),
    )
