from __future__ import annotations

import numpy as np

from localizer.camera import predict_pixels
from localizer.events import LedsChanged
from localizer.geometry import T_world_body_from_pose
from sim.survey_floor import SpotDrive
from survey.observations import label_spot_tracks, lit_state_at_frames, predict_pixels_after_motion
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
