"""`commissioning.sampling.TargetSamples`: which frames it keeps and when it samples, with the
LED phases stretched (the LED coordinator lets robots take turns) and few frames (a loaded
computer)."""

from __future__ import annotations

import numpy as np

from commissioning.measuring import PlacedFrame, place_spots
from commissioning.sampling import TargetSamples
from commissioning.wizard_config import WizardConfig
from localizer.camera import predict_pixels
from localizer.geometry import T_world_body_from_pose
from tests.commissioning.test_measuring import CAM, STEADY, TARGET, TRUE_CAM


def frame(t_s: float, on: bool) -> PlacedFrame:
    pose = (1.0 + 0.1 * t_s, 1.1, 0.2)
    sources = [*STEADY.values(), *([tuple(TARGET)] if on else [])]
    px, ok = predict_pixels(TRUE_CAM, T_world_body_from_pose(*pose), np.array(sources))
    pts = place_spots(CAM, pose, px[ok], 2.5)
    return PlacedFrame(round(t_s * 1e9), frozenset(STEADY), on, px[ok], pts, pose)


def test_stretched_phases_seen_in_few_frames_are_still_followed() -> None:
    cfg = WizardConfig()  # keep_s 3.4 s: less than one stretched cycle here
    samples = TargetSamples(CAM, cfg, [(x, y) for x, y, _ in STEADY.values()])
    for k in range(24):  # 2 frames a second; lit 0-4 s, dark 4-8 s, lit 8-12 s
        t_s = 0.5 * k
        samples.add(frame(t_s, on=not 4.0 <= t_s < 8.0))
        assert (len(samples.points) > 0) == (t_s >= 8.0)  # from the second lit phase on
    assert samples.frames[0].t_ns == 0  # the first lit phase is still kept at 11.5 s
    assert samples.agreed is not None
    np.testing.assert_allclose(samples.agreed.position[:2], TARGET[:2], atol=0.01)


def test_one_long_phase_is_kept_for_max_keep_s_at_most() -> None:
    cfg = WizardConfig()
    samples = TargetSamples(CAM, cfg, [])
    for k in range(60):  # waiting lit for 30 s (a robot would lose its fix)
        samples.add(frame(0.5 * k, on=True))
    kept_s = (samples.frames[-1].t_ns - samples.frames[0].t_ns) * 1e-9
    assert kept_s <= cfg.max_keep_s and len(samples.frames) == 25
    assert samples.points == [] and samples.pairs == 0  # no dark frame: nothing compared
