"""The localizer corrects a calibration handed over slightly wrong, from its own fixes, and the
correction buys accuracy; with the switch off it keeps the calibration as given."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from localizer.calibrated_camera import corrected_camera
from localizer.camera import CameraModel, predict_pixels
from localizer.config import FusionConfig, LocalizerConfig
from localizer.events import OdometryMeasured, PoseEstimate, SpotsObserved
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.robot import RobotGeometry
from localizer.self_calibration import SelfCalibrationConfig
from tests.localizer.cases import grid_positions, strong_radtan_camera

GRID = grid_positions(7, 5, 0.6, 2.5)
MAP = LandmarkMap(np.arange(100, 100 + len(GRID)), GRID)
W = 0.36
TRUE = strong_radtan_camera()
# what Zhang's method hands over: centre 0.6 px off, k1 and k2 5 % off, focal 0.2 % off
GIVEN = corrected_camera(TRUE, [0.6, -0.5, -0.05, 0.05, -0.002, 0.0])


def _pose(t: float) -> tuple[float, float, float]:
    """Parked 0.3 s, 1 m/s along y = 1.25 for 2.5 s, then a turn in place at 1.5 rad/s."""
    if t < 0.3:
        return 0.6, 1.25, 0.0
    if t < 2.8:
        return 0.3 + t, 1.25, 0.0
    return 3.1, 1.25, 1.5 * (t - 2.8)


def _drive(enabled: bool, duration_s: float = 3.5) -> tuple[Localizer, list[float], list[str]]:
    cfg = LocalizerConfig(
        fusion=FusionConfig(
            initial_sigma_m=0.01, initial_sigma_rad=0.005, tilt_from_landmarks=False
        ),
        self_calibration=SelfCalibrationConfig(enabled=enabled),
    )
    loc = Localizer(GIVEN, MAP, RobotGeometry(W, 1.5), cfg)
    loc.set_initial_pose(*_pose(0.0), 0)
    rng = np.random.default_rng(4)
    errors, modes = [], []
    events = [(k * 0.02, "odo") for k in range(1, int(duration_s / 0.02))]
    events += [(0.013 + k / 30, "frame") for k in range(int(duration_s * 30) - 1)]
    for t, kind in sorted(events):
        t_ns = round(t * 1e9)
        if kind == "odo":
            v, w = (0.0, 0.0) if t <= 0.3 else (1.0, 0.0) if t <= 2.8 else (0.0, 1.5)
            loc.handle(OdometryMeasured(t_ns, v - w * W / 2, v + w * W / 2))
            continue
        truth = _pose(t)
        px, ok = predict_pixels(TRUE, T_world_body_from_pose(*truth), GRID)
        px = px[ok] + rng.normal(0.0, 0.1, (int(ok.sum()), 2))
        n = len(px)
        out = loc.handle(SpotsObserved(t_ns, px, np.full(n, 1000.0), np.full(n, 12.0)))[0]
        assert isinstance(out, PoseEstimate)
        modes.append(out.mode)
        errors.append(math.hypot(out.x - truth[0], out.y - truth[1]))
    return loc, errors, modes


def _pixel_error(camera: CameraModel) -> float:
    """The largest pixel distance to the true lens over the grid, seen from (2, 1.25)."""
    T = T_world_body_from_pose(2.0, 1.25, 0.3)
    a, ok = predict_pixels(camera, T, GRID)
    b, _ = predict_pixels(TRUE, T, GRID)
    return float(np.max(np.hypot(*(a[ok] - b[ok]).T)))


def test_the_localizer_corrects_its_calibration_and_gains_accuracy() -> None:
    loc, errors, modes = _drive(True)
    off, errors_off, _ = _drive(False)
    # from its initial pose on this regular grid the localizer first scores a few frames
    # (it does not guess between grid copies); once it has a fix it keeps it
    first = modes.index("landmark")
    assert first * 3 < len(modes) and set(modes[first:]) == {"landmark"}, modes
    assert loc.calibration is not None and loc.calibration.applied.any()
    assert off.calibration is None and off.camera is GIVEN
    assert _pixel_error(loc.camera) < 0.25 * _pixel_error(GIVEN)
    assert abs(loc.camera.cu - TRUE.cu) < 0.2 and abs(loc.camera.cv - TRUE.cv) < 0.2
    late, late_off = np.array(errors[-10:]), np.array(errors_off[-10:])  # the last 0.33 s
    assert np.percentile(late, 95) < 0.5 * np.percentile(late_off, 95), (
        np.percentile(late, 95),
        np.percentile(late_off, 95),
    )


def test_the_switch_is_a_config_field() -> None:
    cfg = dataclasses.replace(
        LocalizerConfig(), self_calibration=SelfCalibrationConfig(enabled=False)
    )
    assert Localizer(GIVEN, MAP, RobotGeometry(W, 1.5), cfg).calibration is None
    assert Localizer(GIVEN, MAP, RobotGeometry(W, 1.5)).calibration is not None
