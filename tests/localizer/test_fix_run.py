"""Re-seeding from a run of fixes the odometry disagrees with (`fix_run`): the link test, the
run's acceptance on hand-made fixes (a stall; a glint taken for a landmark; a regular grid
one spacing off), and the localizer in closed loop on a robot stuck with its wheels
turning."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import predict_pixels
from localizer.config import LocalizerConfig
from localizer.events import OdometryMeasured, PoseEstimate, SpotsObserved
from localizer.fix_run import FixRun, FixRunConfig, TrackPoint, fixes_linked
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.pose import PoseFix
from localizer.robot import RobotGeometry
from sim.cameras import wide_angle_camera
from tests.localizer.cases import grid_positions, irregular_positions

CFG = FixRunConfig(enabled=True)  # off by default (see its docstring); these test it on
SPEED, TURN, SPACING = 1.5, 6.0, 0.4  # m/s, rad/s, m (a 40 cm regular grid)
FRAME_NS = 33_333_333
COV = np.diag([0.003**2, 0.003**2, math.radians(0.05) ** 2])  # a fix of many landmarks
IDS = tuple(range(100, 140))


def _fix(x: float, y: float, theta: float, ids: tuple[int, ...] = IDS) -> PoseFix:
    return PoseFix(x, y, theta, COV, landmark_ids=ids, n_landmarks=len(ids))


def _point(t_ns: int, pose: tuple[float, float, float], ids: tuple[int, ...] = IDS) -> TrackPoint:
    return TrackPoint(t_ns, pose, COV, frozenset(ids))


def _linked(a: TrackPoint, b: TrackPoint, spacing: float = SPACING) -> bool:
    return fixes_linked(a, b, max_speed_m_s=SPEED, max_turn_rad_s=TURN, spacing_m=spacing,
                        config=CFG)  # fmt: skip


def _run() -> FixRun:
    return FixRun(CFG, max_speed_m_s=SPEED, max_turn_rad_s=TURN, spacing_m=SPACING)


def test_a_link_is_the_robots_reach_plus_the_fixes_uncertainty() -> None:
    a = _point(0, (2.0, 1.0, 0.3))
    dt_ns = FRAME_NS  # reach 5 cm, turn 0.2 rad in a frame
    assert _linked(a, _point(dt_ns, (2.0, 1.0, 0.3)))  # stood still
    assert _linked(a, _point(dt_ns, (2.05, 1.0, 0.5)))  # at the limits
    # beyond the reach by 4 sigma of the two fixes' sqrt(2) x 3 mm: no
    assert not _linked(a, _point(dt_ns, (2.05 + 4 * math.sqrt(2) * 0.003, 1.0, 0.3)))
    assert not _linked(a, _point(dt_ns, (2.0, 1.0, 0.3 + 0.2 + math.radians(0.5))))
    assert not _linked(a, _point(0, (2.0, 1.0, 0.3)))  # not later
    # other landmarks: fewer than half of the second fix's shared
    assert not _linked(a, _point(dt_ns, (2.0, 1.0, 0.3), ids=tuple(range(121, 160))))


def test_a_reach_of_half_the_spacing_proves_nothing() -> None:
    a = _point(0, (2.0, 1.0, 0.3))
    # 0.1 s: 15 cm + 3 sigma < 20 cm: linked; 0.13 s: 19.5 cm + 1.3 cm: not, even in place
    assert _linked(a, _point(100_000_000, (2.0, 1.0, 0.3)))
    assert not _linked(a, _point(130_000_000, (2.0, 1.0, 0.3)))
    assert _linked(a, _point(130_000_000, (2.0, 1.0, 0.3)), spacing=1.0)


def test_a_stall_is_accepted_on_the_third_fix_and_followed_while_it_lasts() -> None:
    run = _run()
    run.fused(0, (2.0, 1.0, 0.3), COV, IDS)
    here = (2.024, 1.007, 0.3)  # it hit the pallet 0.8 m/s x 30 ms on; the odometry drives on
    taken = [run.offer(k * FRAME_NS, _fix(*here)) for k in range(1, 8)]
    assert taken == [False, False, True, True, True, True, True]
    # the slip hypothesis lets a fix through right after a re-seed: still accepted ...
    run.fused(8 * FRAME_NS, here, COV, IDS)
    assert run.offer(9 * FRAME_NS, _fix(*here))
    # ... until as many fixes in a row as it took to distrust the odometry are fused
    for k in range(10, 13):
        run.fused(k * FRAME_NS, here, COV, IDS)
    assert not run.accepted
    assert not run.offer(13 * FRAME_NS, _fix(*here))


def test_nothing_without_an_anchor_or_when_disabled() -> None:
    run = _run()
    assert not any(run.offer(k * FRAME_NS, _fix(2.0, 1.0, 0.3)) for k in range(1, 6))
    off = FixRun(FixRunConfig(enabled=False), max_speed_m_s=SPEED, max_turn_rad_s=TURN,
                 spacing_m=SPACING)  # fmt: skip
    off.fused(0, (2.0, 1.0, 0.3), COV, IDS)
    assert not any(off.offer(k * FRAME_NS, _fix(2.0, 1.0, 0.3)) for k in range(1, 6))


@pytest.mark.parametrize("n", [4, 11])
def test_a_glint_beside_a_landmark_in_a_small_view_is_not_accepted(n: int) -> None:
    """A few landmarks in view, one of them taken for the glint beside it (or a tilt taken
    for a translation): the fixes sit 2 cm off, the same on every frame (a world-fixed
    reflection), and the filter (parked, the odometry right) rejects them. Fewer than
    `min_landmarks` cannot outvote a glint: never re-seeded."""
    run = _run()
    few = tuple(range(7, 7 + n))
    run.fused(0, (2.0, 1.0, 0.3), COV, few)
    assert not any(run.offer(k * FRAME_NS, _fix(2.02, 1.0, 0.31, ids=few)) for k in range(1, 30))


def test_a_regular_grid_one_spacing_off_is_not_taken() -> None:
    """Fixes of 40 landmarks one 40 cm spacing from the last fused pose (every spot paired
    with its neighbour's landmark): consistent with each other frame after frame, but never
    reachable from the anchor, right after it or after a second of dead reckoning."""
    shifted = tuple(i + 1 for i in IDS)  # the same spots, each named for its neighbour
    for start_ns in (FRAME_NS, 1_000_000_000):
        run = _run()
        run.fused(0, (2.0, 1.0, 0.3), COV, IDS)
        offers = [run.offer(start_ns + k * FRAME_NS, _fix(2.4, 1.0, 0.3, ids=shifted))
                  for k in range(30)]  # fmt: skip
        assert not any(offers)
        # with the same landmark names (an id-preserving wrong fix) neither
        run = _run()
        run.fused(0, (2.0, 1.0, 0.3), COV, IDS)
        assert not any(run.offer(start_ns + k * FRAME_NS, _fix(2.4, 1.0, 0.3))
                       for k in range(30))  # fmt: skip


def test_a_broken_track_starts_over() -> None:
    run = _run()
    run.fused(0, (2.0, 1.0, 0.3), COV, IDS)
    here = _fix(2.02, 1.0, 0.3)
    assert [run.offer(k * FRAME_NS, here) for k in (1, 2, 3)] == [False, False, True]
    assert not run.offer(4 * FRAME_NS, _fix(2.6, 1.0, 0.3))  # a jump: the track is broken
    # the next ones link to the last re-seeded fix, and need a run of their own
    assert [run.offer(k * FRAME_NS, here) for k in (5, 6, 7)] == [False, False, True]


@pytest.mark.parametrize(
    ("field", "value"),
    [("min_landmarks", 2), ("min_fixes", 0), ("link_gate_chi2", 0.0), ("min_shared_fraction", 1.5),
     ("max_reach_spacing", math.nan)],
)  # fmt: skip
def test_bad_config_names_the_field(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        FixRunConfig(**{field: value})


# -- closed loop -------------------------------------------------------------------------------
ROBOT = RobotGeometry(wheel_base=0.4, max_speed=1.5)
CAMERA = wide_angle_camera("pinhole")


def _stuck_drive(landmarks: LandmarkMap, config: LocalizerConfig) -> tuple[list[float], list[str]]:
    """A robot driving +x at 0.8 m/s, stuck from 2.0 to 3.5 s with its wheels turning on
    (the odometry says it drives on), then driving again; spots projected exactly, 100 Hz
    odometry at 0.8 m/s throughout. Returns per frame the error (m) and the mode."""
    loc = Localizer(CAMERA, landmarks, ROBOT, config)
    v, t_stall, t_free = 0.8, 2.0, 3.5

    def truth(t: float) -> tuple[float, float, float]:
        moving = min(t, t_stall) + max(t - t_free, 0.0)
        return (1.0 + v * moving, 1.6, 0.0)

    loc.set_initial_pose(*truth(0.0), 0)
    events = [(t, 0) for t in range(0, 5_000_000_001, 10_000_000)]
    events += [(t, 1) for t in range(FRAME_NS // 2, 5_000_000_001, FRAME_NS)]
    errors, modes = [], []
    for t_ns, kind in sorted(events):
        if kind == 0:
            loc.handle(OdometryMeasured(t_ns, v, v))
            continue
        pose = truth(t_ns * 1e-9)
        px, ok = predict_pixels(CAMERA, T_world_body_from_pose(*pose), landmarks.positions)
        px = px[ok]
        out = loc.handle(SpotsObserved(t_ns, px, np.full(len(px), 800.0), np.full(len(px), 9.0)))
        est = out[0]
        assert isinstance(est, PoseEstimate)
        errors.append(math.hypot(est.x - pose[0], est.y - pose[1]))
        modes.append(est.mode)
    return errors, modes


@pytest.mark.parametrize("layout", ["irregular", "grid"])
def test_a_robot_stuck_with_its_wheels_turning_keeps_its_pose(layout: str) -> None:
    """On an irregular ceiling and on a regular 40 cm grid (a prediction half a spacing off
    would pair every spot with its neighbour): without the re-seeding the stall's fixes are
    rejected, the dead reckoning runs off (and on the grid the fixes lock on one spacing off);
    with it the pose stays within the two frames before the run is accepted."""
    if layout == "grid":
        positions = grid_positions(16, 9, 0.4)
    else:
        positions = irregular_positions(np.random.default_rng(3), 0, (6.0, 3.2), spacing=0.6)
    landmarks = LandmarkMap(np.arange(1, len(positions) + 1), positions)
    off = LocalizerConfig(fix_run=FixRunConfig(enabled=False))
    err_off, _ = _stuck_drive(landmarks, off)
    err, modes = _stuck_drive(landmarks, LocalizerConfig(fix_run=CFG))
    stall = slice(int(2.0 * 30), int(3.6 * 30))
    assert max(err_off[stall]) > 0.2  # the failure this fixes
    assert max(err[stall]) < 0.06  # two frames of 0.8 m/s before the third fix re-seeds
    assert np.median(err[stall]) < 0.005
    assert modes[stall].count("landmark") >= 0.9 * len(modes[stall])
    after = slice(int(3.6 * 30), None)
    assert max(err[after]) < 0.01  # driving again: tracked as before
