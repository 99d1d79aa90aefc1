"""The switched-spot rule of `commissioning.measuring`, pure: a robot drives under a ceiling
of steady landmarks while the target's LED is switched (lit 0.6 s, dark 0.5 s, as the wizard
does), its frames made with a camera whose calibration is off by what a real one is (focal
+-0.2 %, centre 0.6 px, distortion 5 %) and placed with a biased pose estimate. A dim glint
beside a landmark drops in and out of detection."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest

from commissioning.doubt import expected_in_view
from commissioning.geometry import point_in_view_from_poses
from commissioning.measuring import (
    PlacedFrame,
    agreement,
    lone_spots,
    place_spots,
    switch_record,
    switched_spot,
)
from localizer.camera import predict_pixels
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera

CAM = wide_angle_camera("pinhole")  # what the robot believes
TRUE_CAM = dataclasses.replace(
    CAM, fu=CAM.fu * 1.002, fv=CAM.fv * 0.998, cu=CAM.cu + 0.6, cv=CAM.cv - 0.6,
    distortion=CAM.distortion * 1.05,
)  # fmt: skip
STEADY = {10 + 3 * j + i: (1.2 * i, 1.2 * j, 2.5) for j in range(3) for i in range(3)}
TARGET = np.array([1.7, 1.5, 2.5])
GLINT = np.array([1.45, 1.2, 2.5])  # 25 cm beside landmark 14 at (1.2, 1.2)
FRAME_NS = 33_333_333
LIT_NS, DARK_NS, SETTLE_NS = 600_000_000, 500_000_000, 50_000_000
MATCH = {"match_m": 0.15, "margin_px": 10.0}


def target_lit(t_ns: int) -> bool | None:
    """The target's LED by the cycle (lit first); None within settle of a switch."""
    phase = t_ns % (LIT_NS + DARK_NS)
    since = phase if phase < LIT_NS else phase - LIT_NS
    return None if since < SETTLE_NS else phase < LIT_NS


def drive(
    seconds: float,
    *,
    target_alive: bool,
    glint: Callable[[int], bool],
    dark_with_target: frozenset[int] = frozenset(),
    seed: int = 7,
) -> list[PlacedFrame]:
    """Frames of a robot driving along x at 0.4 m/s; `glint(k)` says whether frame k shows
    the glint; `dark_with_target` are landmarks a robot darkens exactly with the target."""
    rng = np.random.default_rng(seed)
    frames = []
    for k in range(round(seconds * 1e9 / FRAME_NS)):
        t_ns = k * FRAME_NS
        on = target_lit(t_ns)
        if on is None:
            continue  # the wizard takes no frame while the target's LED settles
        truth = (0.9 + 0.4 * t_ns * 1e-9, 1.1, 0.2)
        estimate = (truth[0] + 0.003, truth[1] - 0.002, truth[2] + 0.002)  # a fix's error
        lit = frozenset(STEADY) - (frozenset() if on else dark_with_target)
        sources = [STEADY[i] for i in sorted(lit)]
        if on and target_alive:
            sources.append(tuple(TARGET))
        if glint(k):
            sources.append(tuple(GLINT))
        px, ok = predict_pixels(TRUE_CAM, T_world_body_from_pose(*truth), np.array(sources))
        px = px[ok] + rng.normal(0.0, 0.1, (int(ok.sum()), 2))
        pts = place_spots(CAM, estimate, px, 2.5)
        frames.append(PlacedFrame(t_ns, lit, on, px, pts, estimate))
    return frames


def windows(frames: list[PlacedFrame], keep_ns: int = 3_400_000_000) -> list[list[PlacedFrame]]:
    """The frames the wizard keeps at each lit frame (the last `keep_ns`)."""
    return [
        [g for g in frames[: k + 1] if g.t_ns >= f.t_ns - keep_ns]
        for k, f in enumerate(frames)
        if f.target_on
    ]


def flicker(seed: int) -> Callable[[int], bool]:
    seen = np.random.default_rng(seed).random(1000) < 0.5
    return lambda k: bool(seen[k])


def test_a_spot_that_merely_flickers_is_never_taken_for_the_switched_led() -> None:
    frames = drive(4.0, target_alive=False, glint=flicker(1))
    # the hazard: paired with the latest dark frame, the glint is often the one lone spot
    lone_glint = 0
    for w in windows(frames):
        off = next((f for f in reversed(w) if not f.target_on), None)
        if off is not None:
            lone = lone_spots(CAM, w[-1], off, **MATCH)
            lone_glint += int(len(lone) == 1 and np.hypot(*(lone[0, :2] - GLINT[:2])) < 0.02)
    assert lone_glint >= 10
    found = [switched_spot(CAM, w, **MATCH, min_cycles=2) for w in windows(frames)]
    assert all(f is None or f.point is None for f in found)
    named = [p for f in found if f is not None for p in f.flickering]
    assert len(named) >= 10  # it is named for the prompt, where it is
    np.testing.assert_allclose(np.median(named, axis=0), GLINT[:2], atol=0.01)


def test_the_switched_led_is_measured_from_its_second_lit_phase_while_the_robot_moves() -> None:
    frames = drive(3.5, target_alive=True, glint=flicker(2))
    samples, first_ns = [], None
    for w in windows(frames):
        f = switched_spot(CAM, w, **MATCH, min_cycles=2)
        if f is not None and f.point is not None:
            first_ns = w[-1].t_ns if first_ns is None else first_ns
            samples.append(f.point)
            truth = (0.9 + 0.4 * w[-1].t_ns * 1e-9, 1.1, 0.2)
            px, _ = predict_pixels(TRUE_CAM, T_world_body_from_pose(*truth), TARGET[None])
            assert f.pixel is not None
            np.testing.assert_allclose(f.pixel, px[0], atol=0.5)
    # lit 0-0.6 s, dark 0.6-1.1 s, lit again from 1.1 s (+ settle): not one cycle earlier
    assert first_ns is not None and 1.15e9 <= first_ns < 1.2e9
    assert len(samples) >= 25  # every lit frame of the second and third lit phases
    np.testing.assert_allclose(np.array(samples)[:, :2], np.tile(TARGET[:2], (len(samples), 1)),
                               atol=0.01)  # fmt: skip
    agreed = agreement(samples, agree_m=0.03, needed=5)
    assert agreed is not None and agreed.spread_m < 0.005
    # the calibration and pose errors leave 7 mm
    assert np.hypot(*(np.array(agreed.position[:2]) - TARGET[:2])) < 0.01


def test_a_landmark_darkened_in_step_with_the_target_is_not_taken_for_it() -> None:
    frames = drive(3.5, target_alive=False, glint=lambda k: False, dark_with_target=frozenset({14}))
    found = [switched_spot(CAM, w, **MATCH, min_cycles=2) for w in windows(frames)]
    assert any(f is not None and f.candidates == 1 for f in found)  # 14 is lone in each pair
    assert all(f is None or f.point is None for f in found)
    record = switch_record(CAM, STEADY[14], frames, **MATCH)
    assert not record.broken and record.in_step == {14}  # it followed: but so did 14's LED
    assert record.lit_phases == 4 and record.dark_phases == 3


def test_the_record_counts_misses_extras_and_only_frames_that_saw_the_place() -> None:
    def shown(k: int) -> bool:  # a glint blinking with the cycle's period (33 frames), late
        return 6 <= k % 33 < 24

    frames = drive(2.3, target_alive=False, glint=shown)
    rec = switch_record(CAM, GLINT, frames, **MATCH)
    k = [round(f.t_ns / FRAME_NS) for f in frames]
    lit = [f.target_on for f in frames]
    assert rec.misses == sum(on and not shown(i) for i, on in zip(k, lit, strict=True)) >= 8
    assert rec.extras == sum(not on and shown(i) for i, on in zip(k, lit, strict=True)) >= 8
    assert (rec.lit_phases, rec.dark_phases) == (3, 2) and rec.broken
    far = np.array([30.0, 1.1, 2.5])  # never in view: nothing counts
    assert switch_record(CAM, far, frames, **MATCH) == type(rec)(0, 0, 0, 0)


@pytest.mark.parametrize("seed", [0, 1])
def test_in_view_from_many_poses_is_expected_in_view_of_each(seed: int) -> None:
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-2, 4, 300), rng.uniform(-2, 4, 300),
                             rng.uniform(-np.pi, np.pi, 300)])  # fmt: skip
    p = np.array([1.0, 1.0, 2.5])
    batch = point_in_view_from_poses(CAM, poses, p, margin_px=10.0)
    one = [bool(expected_in_view(CAM, tuple(q), p[None], margin_px=10.0)[0]) for q in poses]
    assert batch.tolist() == one and 20 < sum(one) < 280
