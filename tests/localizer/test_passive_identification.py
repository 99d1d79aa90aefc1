"""The localizer on passive lights (never switched): identified by geometry, then tracked."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.config import LocalizerConfig
from localizer.events import LedRequest, OdometryMeasured, PoseEstimate, SpotsObserved
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.passive_config import PassiveConfig
from localizer.passive_identification import light_radius_px, passive_settings
from localizer.robot import RobotGeometry
from tests.localizer.cases import fisheye_camera, irregular_positions

CAM = fisheye_camera(T_body_camera_upward(height=0.3))
ROBOT = RobotGeometry(0.36, 1.5)
SIGMA_M = 0.05


def passive_map(positions: np.ndarray) -> LandmarkMap:
    n = len(positions)
    return LandmarkMap(
        np.arange(1, n + 1), positions, np.full(n, SIGMA_M), np.ones(n, bool), np.full(n, 0.6)
    )


def drive(
    lmap: LandmarkMap, start: tuple[float, float, float], seconds: float, speed: float,
    *, start_pose: tuple[float, float, float] | None = None, seed: int = 2,
) -> tuple[list[tuple[float, str, float]], Localizer, list[object]]:  # fmt: skip
    """Straight ahead at `speed` from `start` (parked for the first second), odometry at
    50 Hz, spots at 15 Hz, each light's centroid off by SIGMA_M (fixed per light)."""
    rng = np.random.default_rng(seed)
    off = np.column_stack([rng.normal(0, SIGMA_M, (len(lmap), 2)), np.zeros(len(lmap))])
    truth_p = lmap.positions + off
    loc = Localizer(CAM, lmap, ROBOT)
    if start_pose is not None:
        loc.set_initial_pose(*start_pose, 0, radius_m=1.0)
    events = [(k * 20_000_000, 0) for k in range(1, int(seconds * 50))]
    events += [(k * 66_666_667, 1) for k in range(1, int(seconds * 15))]
    out: list[tuple[float, str, float]] = []
    extra: list[object] = []
    for t_ns, kind in sorted(events):
        t = t_ns * 1e-9
        v = speed if t > 1.0 else 0.0
        d = speed * max(t - 1.0, 0.0)
        pose = (start[0] + d * math.cos(start[2]), start[1] + d * math.sin(start[2]), start[2])
        if kind == 0:
            loc.handle(OdometryMeasured(t_ns, v, v))
            continue
        px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), truth_p)
        px = px[ok] + rng.normal(0.0, 0.5, (int(ok.sum()), 2))
        res = loc.handle(SpotsObserved(t_ns, px, np.full(len(px), 9e4), np.full(len(px), 900.0)))
        est = res[0]
        extra += res[1:]
        err = math.hypot(est.x - pose[0], est.y - pose[1]) if isinstance(est, PoseEstimate) else -1
        out.append((t, est.mode, err))
    return out, loc, extra


def test_cold_start_on_irregular_lights_identifies_without_blinking_and_tracks() -> None:
    lights = irregular_positions(np.random.default_rng(3), 0, (24.0, 12.0), spacing=2.5, z=3.0)
    out, _, extra = drive(passive_map(lights), (4.0, 6.0, 0.1), 6.0, 1.0)
    assert not any(isinstance(o, LedRequest) for o in extra)  # passive: never switched
    first = next(t for t, mode, _ in out if mode == "landmark")
    assert first < 0.5  # parked: identified from the first frames
    errs = [e for t, mode, e in out if mode == "landmark"]
    assert len(errs) >= 0.9 * len(out) and max(errs) < 0.06


def test_cold_start_on_a_regular_grid_says_why_and_a_start_pose_decides() -> None:
    grid = np.array([[i * 3.0, j * 3.7, 3.0] for i in range(8) for j in range(6)])
    lmap = passive_map(grid)
    out, loc, _ = drive(lmap, (10.0, 9.0, 0.3), 1.0, 0.0)  # parked in the middle
    assert all(mode == "identifying" for _, mode, _ in out)  # no guess
    status = loc.passive_status
    assert status is not None and status.status == "ambiguous" and "regular layout" in status.reason
    out, _, _ = drive(lmap, (10.0, 9.0, 0.3), 3.0, 0.8, start_pose=(10.3, 8.8, 0.35))
    errs = [e for _, mode, e in out if mode == "landmark"]
    assert len(errs) >= 0.9 * len(out) and max(errs) < 0.06


def test_settings_widen_the_detector_and_windows_to_the_panels_only() -> None:
    lights = irregular_positions(np.random.default_rng(3), 0, (24.0, 12.0), spacing=2.5, z=3.0)
    lmap = passive_map(lights)
    r = light_radius_px(CAM, lmap)  # 0.3 m at 2.7 m through ~300 px focal length
    assert 25 < r < 45
    cfg = passive_settings(LocalizerConfig(), CAM, lmap)
    assert cfg.detection.max_area_px >= math.pi * r * r
    assert cfg.tracking.min_half_size_px > r
    points = LandmarkMap(lmap.ids, lmap.positions, passive=lmap.passive)
    assert passive_settings(LocalizerConfig(), CAM, points) == LocalizerConfig()
    off = LocalizerConfig(passive=PassiveConfig(mode="off"))
    assert passive_settings(off, CAM, lmap) == off


def test_map_records_round_trip_passive_size_and_sigma() -> None:
    recs = [
        {"id": 1, "x": 0.0, "y": 0.0, "z": 3.0, "passive": True, "size_m": 0.6, "sigma_m": 0.04},
        {"id": 2, "x": 3.0, "y": 0.0, "z": 3.0},
    ]
    lmap = LandmarkMap.from_records(recs)
    assert lmap.passive is not None and lmap.passive.tolist() == [True, False]
    assert lmap.sizes is not None and lmap.sizes.tolist() == [0.6, 0.0]
    assert lmap.sigma_at(0) == 0.04 and lmap.sigma_at(1) is None
    assert LandmarkMap.from_records(lmap.to_records()).to_records() == lmap.to_records()
    assert not PassiveConfig().applies_to(lmap)  # auto: only a map that is all passive
    assert PassiveConfig(mode="all").applies_to(lmap)
    bad = [{"id": 1, "x": 0.0, "y": 0.0, "z": 3.0, "passive": "yes"}]
    with pytest.raises(ValueError, match=r"map\.json: landmark 1: 'passive' must be true or false"):
        LandmarkMap.from_records(bad, source="map.json")
    with pytest.raises(ValueError, match="'size_m' must be a non-negative number"):
        LandmarkMap.from_records([{**recs[1], "size_m": -1}], source="map.json")
