from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

from commissioning.doubt import DoubtConfig, DoubtTracker, expected_in_view
from localizer.events import PoseEstimate
from sim.cameras import wide_angle_camera

CAM = wide_angle_camera("pinhole")
GRID = {10 + 4 * j + i: (float(i), float(j), 2.5) for j in range(3) for i in range(4)}
POSE = (1.5, 1.0, 0.3)
CFG = DoubtConfig(window=40, min_chances=20, max_used_fraction=0.1, settle_s=0.0)


def in_view(pose: tuple[float, float, float] = POSE, margin_px: float = 25.0) -> list[int]:
    ids = sorted(GRID)
    pts = np.array([GRID[i] for i in ids])
    ok = expected_in_view(
        CAM, pose, pts, margin_px=margin_px, max_off_axis_rad=CFG.max_off_axis_rad
    )
    return [i for i, v in zip(ids, ok, strict=True) if v]


_T = [0]


def estimate(used: list[int], *, mode: str = "landmark", sigma_m: float = 0.01) -> PoseEstimate:
    """The next frame's estimate (frames 0.1 s apart: every one is a chance)."""
    _T[0] += 100_000_000
    return estimate_at(_T[0], used, mode=mode, sigma_m=sigma_m)


def estimate_at(
    t_ns: int, used: list[int], *, mode: str = "landmark", sigma_m: float = 0.01
) -> PoseEstimate:
    cov = np.diag([sigma_m**2 / 2, sigma_m**2 / 2, 1e-4])
    return PoseEstimate(t_ns, *POSE, cov, mode, tuple(used))  # type: ignore[arg-type]


def expecting(pose: PoseEstimate, lit: Iterable[int], unsure: Iterable[int] = ()) -> PoseEstimate:
    """The estimate as the localizer gives it: the landmarks it expected lit (all of `lit`
    but those being switched, `unsure`; the tracker keeps those in its field of view)."""
    return dataclasses.replace(pose, expected_ids=tuple(sorted(set(lit) - set(unsure))))


def tracker() -> DoubtTracker:
    t = DoubtTracker(CFG)
    t.set_map(GRID)
    return t


def test_expected_in_view_matches_the_camera_and_its_margin() -> None:
    view = in_view()
    assert len(view) >= 4
    wide = in_view(margin_px=0.0)
    assert set(view) <= set(wide)
    far = expected_in_view(CAM, (20.0, 20.0, 0.0), np.array(list(GRID.values())), margin_px=0)
    assert not far.any()
    assert expected_in_view(CAM, POSE, np.zeros((0, 3)), margin_px=0).shape == (0,)


def test_a_landmark_in_view_but_never_used_is_doubted_after_enough_chances() -> None:
    view = in_view()
    bad = view[0]
    t = tracker()
    for k in range(CFG.min_chances):
        assert bad not in t.doubted(), k
        t.observe("r1", CAM, expecting(estimate([i for i in view if i != bad]), GRID))
    assert list(t.doubted()) == [bad]
    d = t.doubted()[bad]
    assert (d.chances, d.used) == (CFG.min_chances, 0)
    assert d.reason == f"expected in view {CFG.min_chances} times, used 0"
    assert t.record(view[1]).chances == CFG.min_chances and t.record(view[1]).used == 20


def test_the_used_share_decides_within_the_window() -> None:
    view = in_view()
    bad = view[0]
    t = tracker()
    # used in 2 of 20 chances (10 %): doubted; a third use (15 %) clears it
    for k in range(20):
        used = view if k in (3, 9) else [i for i in view if i != bad]
        t.observe("r1", CAM, expecting(estimate(used), GRID))
    assert bad in t.doubted()
    t.observe("r1", CAM, expecting(estimate(view), GRID))
    assert bad not in t.doubted()
    # the window forgets: 40 more misses make it doubted again
    for _ in range(40):
        t.observe("r1", CAM, expecting(estimate([i for i in view if i != bad]), GRID))
    assert t.record(bad).chances == 40 and t.record(bad).used == 0
    assert bad in t.doubted()


def test_frames_that_are_no_chance_do_not_count() -> None:
    view = in_view()
    bad, others = view[0], view[1:]
    t = tracker()
    for _ in range(30):
        t.observe(
            "r1", CAM, expecting(estimate(others, mode="dead_reckoning"), GRID)
        )  # not localized
        t.observe("r1", CAM, expecting(estimate(others, sigma_m=0.2), GRID))  # too uncertain
        t.observe("r1", CAM, expecting(estimate(others[:1]), GRID))  # used one other only
        t.observe("r1", CAM, expecting(estimate(others), set(GRID) - {bad}))  # its LED was dark
    assert t.record(bad).chances == 0 and t.doubted() == {}
    t.set_map({**GRID, 99: (9.0, 9.0, 2.5)})
    for _ in range(30):
        t.observe("r1", CAM, expecting(estimate(others), {*GRID, 99}))
    assert t.record(99).chances == 0  # lit, but out of view


def test_moving_a_landmark_in_the_map_forgets_its_history() -> None:
    view = in_view()
    bad = view[0]
    t = tracker()
    for _ in range(25):
        t.observe("r1", CAM, expecting(estimate([i for i in view if i != bad]), GRID))
    assert bad in t.doubted()
    t.set_map(GRID)  # unchanged: kept
    assert bad in t.doubted()
    moved = dict(GRID)
    moved[bad] = (GRID[bad][0] + 0.02, GRID[bad][1], 2.5)
    t.set_map(moved)
    assert bad not in t.doubted() and t.record(bad).chances == 0
    assert t.record(view[1]).chances == 25  # the others are kept
    del moved[view[1]]
    t.set_map(moved)
    assert t.record(view[1]).chances == 0


def test_a_robots_updates_count_at_most_every_min_interval() -> None:
    view = in_view()
    t = tracker()
    for k in range(30):  # 30 frames at 25 Hz: every third is 0.1 s or more after the last
        pose = PoseEstimate(k * 40_000_000, *POSE, np.eye(3) * 1e-6, "landmark", tuple(view))
        t.observe("r1", CAM, expecting(pose, GRID))
        t.observe("r2", CAM, expecting(pose, GRID))  # another robot counts on its own
    assert t.record(view[0]).chances == 2 * 10


def test_an_led_far_off_the_optical_axis_is_not_expected_even_inside_the_image() -> None:
    # fisheye: 40 degrees off axis lies well inside the image; the camera is 0.3 m above the
    # body origin, the LEDs 2.2 m above it, along the body's y axis (the image's rows)
    cam = wide_angle_camera("fisheye")
    angles = np.radians([20.0, 38.0, 42.0, 50.0])
    pts = np.column_stack([np.zeros(4), 2.2 * np.tan(angles), np.full(4, 2.5)])
    limit = math.radians(40.0)
    near = expected_in_view(cam, (0.0, 0.0, 0.0), pts, margin_px=0.0, max_off_axis_rad=limit)
    assert near.tolist() == [True, True, False, False]
    anywhere = expected_in_view(cam, (0.0, 0.0, 0.0), pts, margin_px=0.0)
    assert anywhere.tolist() == [True, True, True, True]  # all project inside the image
    # the default rule: 40 degrees
    assert DoubtConfig().max_off_axis_rad == limit


def test_a_robot_counts_only_once_settled_after_its_first_fix() -> None:
    cfg = DoubtConfig(window=200, min_chances=20, settle_s=1.0)
    view = in_view()
    bad = view[0]
    t = DoubtTracker(cfg)
    t.set_map(GRID)
    others = [i for i in view if i != bad]
    t0 = 10_000_000_000
    for k in range(20):  # 2 s of fixes, 0.1 s apart: the first second is no chance
        t.observe("r1", CAM, expecting(estimate_at(t0 + k * 100_000_000, others), GRID))
    assert t.record(bad).chances == 10
    # dead reckoning in between keeps the robot settled
    t.observe(
        "r1",
        CAM,
        expecting(estimate_at(t0 + 20 * 100_000_000, others, mode="dead_reckoning"), GRID),
    )
    t.observe("r1", CAM, expecting(estimate_at(t0 + 21 * 100_000_000, others), GRID))
    assert t.record(bad).chances == 11
    # lost, identifying again (or a frame without a pose): it settles again
    for k, lost in enumerate(("lost", "identifying", None)):
        start = t0 + (100 + 100 * k) * 100_000_000
        if lost is None:
            t.unlocalized("r1")
        else:
            t.observe(
                "r1", CAM, expecting(estimate_at(start - 100_000_000, others, mode=lost), GRID)
            )
        for j in range(15):
            t.observe("r1", CAM, expecting(estimate_at(start + j * 100_000_000, others), GRID))
        assert t.record(bad).chances == 11 + 5 * (k + 1), lost
    # another robot settles on its own
    t.observe("r2", CAM, expecting(estimate_at(t0 + 400 * 100_000_000, others), GRID))
    assert t.record(bad).chances == 26


def test_an_led_switched_around_the_frame_is_no_chance() -> None:
    view = in_view()
    bad, others = view[0], view[1:]
    t = tracker()
    for _ in range(30):
        t.observe("r1", CAM, expecting(estimate(others), GRID, {bad}))  # darkened by a probe
    assert t.record(bad).chances == 0 and t.doubted() == {}
    assert t.record(others[0]).chances == 30  # the others still count
    t.observe("r1", CAM, expecting(estimate(others), GRID, {others[0]}))
    assert t.record(bad).chances == 1 and t.record(others[0]).chances == 30


def test_with_the_defaults_a_landmark_that_stops_being_used_is_doubted_after_54_misses() -> None:
    cfg = DoubtConfig()
    assert (cfg.window, cfg.min_chances, cfg.max_used_fraction) == (60, 60, 0.1)
    view = in_view()
    bad = view[0]
    t = DoubtTracker(cfg)
    t.set_map(GRID)
    t0 = 50_000_000_000
    frames = iter(range(10_000))

    def frame(used: list[int]) -> None:
        t.observe("r1", CAM, expecting(estimate_at(t0 + next(frames) * 100_000_000, used), GRID))

    for _ in range(20 + 200):  # settling (2 s), then a long record of uses
        frame(view)
    assert t.record(bad).chances == 60 and t.record(bad).used == 60
    for k in range(54):  # its LED died: 54 misses leave 6 uses (10 %) in the last 60
        assert bad not in t.doubted(), k
        frame([i for i in view if i != bad])
    assert t.doubted()[bad].reason == "expected in view 60 times, used 6"
