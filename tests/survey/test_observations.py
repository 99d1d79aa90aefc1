from __future__ import annotations

import numpy as np

from localizer.camera import CameraModel, predict_pixels
from localizer.events import LedsChanged
from localizer.geometry import T_world_body_from_pose
from sim.survey_floor import SpotDrive
from survey.observations import (
    LabelledObservations,
    label_spot_tracks,
    lit_state_at_frames,
    predict_pixels_after_motion,
)
from survey.odometry_chain import relative_motions, wheel_intervals


def _motions(drive: SpotDrive) -> np.ndarray:
    w = wheel_intervals(drive.odom_t_ns, drive.odom_v, drive.frame_t_ns)
    return relative_motions(w, drive.wheel_base_m)


def test_spots_carried_by_the_wheels_land_on_the_next_frame(spot_drive: SpotDrive) -> None:
    d = spot_drive
    f = len(d.frame_t_ns) // 2
    motion = _motions(d)[f]
    p = np.array(list(d.landmarks_true.values()))
    px0, ok0 = predict_pixels(d.camera_true, T_world_body_from_pose(*d.truth[f]), p)
    px1, ok1 = predict_pixels(d.camera_true, T_world_body_from_pose(*d.truth[f + 1]), p)
    keep = ok0 & ok1
    pred, valid = predict_pixels_after_motion(d.camera, px0[keep], motion, 2.5)
    assert valid.all()
    # within the tracking gate though the ceiling is uneven and the calibration off
    assert np.max(np.linalg.norm(pred - px1[keep], axis=1)) < 2.0


def test_blinks_name_tracks_and_names_are_right(spot_drive: SpotDrive) -> None:
    d = spot_drive
    ids = sorted(d.landmarks_true)
    obs = label_spot_tracks(
        d.camera, ids, d.frame_t_ns.tolist(), d.frame_spots, _motions(d), d.leds, ceiling_z_m=2.5
    )
    named = obs.landmark_id >= 0
    assert obs.seen_ids() == set(ids)
    assert named.mean() > 0.5
    # every named spot lies where its landmark projects (the truth is known here)
    wrong = 0
    for f, lid, px in zip(obs.frame[named], obs.landmark_id[named], obs.pixels[named], strict=True):
        q, ok = predict_pixels(
            d.camera_true, T_world_body_from_pose(*d.truth[f]), d.landmarks_true[int(lid)][None]
        )
        wrong += int(not ok[0] or np.linalg.norm(q[0] - px) > 2.0)
    assert wrong <= 0.02 * int(named.sum())
    # confident names (two or more votes) are never wrong
    sure = obs.name_votes >= 2
    assert sure.sum() > 0


def test_led_state_at_frames_is_the_one_in_force() -> None:
    leds = [LedsChanged(10, all_lit=True), LedsChanged(20, frozenset({1}))]
    states = lit_state_at_frames([5, 10, 19, 20, 99], leds)
    assert states == [None, leds[0], leds[0], leds[1], leds[1]]


_FRAME_NS = 33_333_333
_WINDOWS = [(10, 16), (30, 36), (50, 56), (70, 76)]  # frames landmark 1 is dark


def _blinks_of_one() -> list[LedsChanged]:
    """Landmark 1 dark in each of `_WINDOWS` (stamped 5 ms before the window's first frame),
    every landmark lit in between."""
    leds = [LedsChanged(0, all_lit=True)]
    for a, b in _WINDOWS:
        leds.append(LedsChanged(a * _FRAME_NS - 5_000_000, frozenset({2, 3})))
        leds.append(LedsChanged(b * _FRAME_NS - 5_000_000, all_lit=True))
    return leds


def _standing_still(
    camera: CameraModel, spots: list[list[tuple[float, float]]]
) -> LabelledObservations:
    n = len(spots)
    return label_spot_tracks(
        camera,
        [1, 2, 3],
        [f * _FRAME_NS for f in range(n)],
        [np.array(s, dtype=np.float64).reshape(-1, 2) for s in spots],
        np.zeros((n - 1, 3)),
        _blinks_of_one(),
        ceiling_z_m=2.5,
    )


def _dark(f: int) -> bool:
    return any(a <= f < b for a, b in _WINDOWS)


def test_a_track_seen_while_its_name_was_dark_is_not_that_landmark(spot_drive: SpotDrive) -> None:
    # a spot that vanished once during landmark 1's dark window (chance: an occlusion) but
    # stayed in view through its three other dark windows
    a = (320.0, 240.0)
    spots = [[] if 10 <= f < 16 else [a] for f in range(90)]
    obs = _standing_still(spot_drive.camera, spots)
    assert obs.tracks == 1
    assert obs.named == 0 and set(obs.landmark_id.tolist()) == {-1}
    # the same vanishing without the windows against it names the track
    spots = [[] if 10 <= f < 16 else [a] for f in range(28)]
    obs = _standing_still(spot_drive.camera, spots)
    assert obs.named == 1 and set(obs.landmark_id.tolist()) == {1}


def test_of_two_tracks_at_once_the_one_with_far_fewer_votes_loses_the_name(
    spot_drive: SpotDrive,
) -> None:
    # b is landmark 1 (dark in all four windows); a appears after the third and vanishes by
    # chance in the fourth: one vote for 1, nothing against, but b is in view meanwhile
    a, b = (320.0, 240.0), (380.0, 240.0)
    spots = [([] if f < 60 or _dark(f) else [a]) + ([] if _dark(f) else [b]) for f in range(90)]
    obs = _standing_still(spot_drive.camera, spots)
    assert obs.tracks == 2 and obs.named == 1
    named = obs.landmark_id >= 0
    assert np.all(obs.pixels[named][:, 0] == b[0])
    assert obs.conflicts == {} and obs.votes == {1: 4}


def test_two_spots_vanishing_at_every_blink_of_one_address_are_both_named_and_reported(
    spot_drive: SpotDrive,
) -> None:
    # two landmarks answering to one radio address: both spots go dark in each of its windows
    a, b = (320.0, 240.0), (380.0, 240.0)
    spots = [[] if _dark(f) else [a, b] for f in range(90)]
    obs = _standing_still(spot_drive.camera, spots)
    assert obs.tracks == 2 and obs.named == 2
    assert set(obs.landmark_id.tolist()) == {1}
    assert obs.conflicts == {1: 90 - 4 * 6}  # every frame the two were seen together


def test_tracks_seen_together_with_one_name_and_equal_votes_both_lose_it(
    spot_drive: SpotDrive,
) -> None:
    # each vanished in two of landmark 1's windows (and was out of view in the others:
    # nothing against either), seen together in between: which one is 1 is not known
    a, b = (320.0, 240.0), (380.0, 240.0)
    spots = [
        ([a] if 6 <= f < 40 and not _dark(f) else [])
        + ([b] if 20 <= f < 60 and not _dark(f) else [])
        for f in range(62)
    ]
    obs = _standing_still(spot_drive.camera, spots)
    assert obs.tracks == 2 and obs.named == 0
