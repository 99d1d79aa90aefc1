from __future__ import annotations

import asyncio

import numpy as np
import pytest

from localizer.camera import predict_pixels
from localizer.events import FrameObserved, OdometryMeasured
from sim.virtual_site import VirtualSite

T0 = 5_000_000_000_000


def _run(site: VirtualSite, seconds: float, step_ms: int = 20, start: int = T0) -> list:
    out = []
    for k in range(1, round(seconds * 1000 / step_ms) + 1):
        out += site.step(start + k * step_ms * 1_000_000)
    return out


def test_live_site_streams_frames_and_odometry_per_robot() -> None:
    site = VirtualSite("demo")
    assert site.step(T0) == []
    samples = _run(site, 1.0)
    assert site.robot_names == ["r1", "r2", "r3"]
    for name in site.robot_names:
        frames = [
            s.event for s in samples if s.robot == name and isinstance(s.event, FrameObserved)
        ]
        odo = [
            s.event for s in samples if s.robot == name and isinstance(s.event, OdometryMeasured)
        ]
        assert 29 <= len(frames) <= 31 and 99 <= len(odo) <= 100
        assert frames[0].image.shape == (480, 640) and frames[0].image.dtype == np.uint8
        assert all(T0 <= f.t_ns <= T0 + 1_000_000_000 for f in frames)
    times = [s.event.t_ns for s in samples]
    assert times == sorted(times)
    x, _, _ = site.true_pose("r1")
    assert x > 0.6 + 0.2  # drove toward (5.4, 0.6)


def test_cameras_see_the_leds_the_radio_switches() -> None:
    site = VirtualSite("demo", seed=11)
    site.step(T0)
    frame = next(
        s.event for s in _run(site, 0.2) if s.robot == "r2" and isinstance(s.event, FrameObserved)
    )
    assert int((frame.image > 60).sum()) > 10

    async def all_off() -> list[bool]:
        return [await site.radio.set_pin(lm.address, False) for lm in site.world.landmarks.values()]

    site.radio.timeout_s = 0.0
    site.radio.loss = 0.0
    site.radio.latency_s = (0.0, 0.0)
    asyncio.run(all_off())
    assert site.world.lit_ids() == set()
    later = [s.event for s in _run(site, 0.2, start=T0 + 200_000_000) if s.robot == "r2"]
    frames = [e for e in later if isinstance(e, FrameObserved)]
    # The only bright things left: the lamp and glint (not in r2's view) -> no spots.
    assert max(int((f.image > 60).sum()) for f in frames) == 0


def test_rendered_spots_match_the_nominal_camera_within_calibration_error() -> None:
    site = VirtualSite("demo", seed=3)
    site.step(T0)
    frame = next(
        s.event for s in _run(site, 0.1) if s.robot == "r1" and isinstance(s.event, FrameObserved)
    )
    x, y, th = site.true_pose("r1")
    from localizer.geometry import T_world_body_from_pose

    lm = site.world.landmarks[100]
    px, valid = predict_pixels(
        site.camera("r1"), T_world_body_from_pose(x, y, th), lm.p_surveyed[None]
    )
    assert valid[0]
    u, v = np.round(px[0]).astype(int)
    patch = frame.image[v - 6 : v + 7, u - 6 : u + 7]
    assert patch.max() > 100  # the spot lies within a few pixels of the prediction


def test_same_seed_same_samples() -> None:
    a, b = VirtualSite("hostile", seed=2), VirtualSite("hostile", seed=2)
    a.step(0), b.step(0)
    sa, sb = _run(a, 0.3, start=0), _run(b, 0.3, start=0)
    fa = [s.event.image for s in sa if isinstance(s.event, FrameObserved)]
    fb = [s.event.image for s in sb if isinstance(s.event, FrameObserved)]
    assert len(fa) == len(fb) > 5
    for ia, ib in zip(fa, fb, strict=True):
        np.testing.assert_array_equal(ia, ib)
    assert a.landmark_records() == b.landmark_records()


def test_unknown_robot_is_named() -> None:
    with pytest.raises(KeyError, match="unknown robot 'zz'"):
        VirtualSite("paper_testbed").camera("zz")
