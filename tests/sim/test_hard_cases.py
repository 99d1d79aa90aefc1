"""The scenario options for the hard cases of the robustness matrix: the wide
radial-tangential lens, calibration-error levels, irregular grids and uneven ceilings, drive
limits, kidnaps, wheel slip, floor tilt and dead LEDs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.events import OdometryMeasured
from sim.cameras import (
    CALIBRATION_LEVELS,
    CalibrationError,
    miscalibrated_camera,
    wide_angle_camera,
)
from sim.robot import FloorTilt, FramePose, OdometryModel, SimRobot, SlipPatch, floor_height
from sim.routes import Drive, DriveLimits, Goto, Kidnap, Route, TurnTo, Wait
from sim.scenario import scenario_from_dict


def _doc(**extra: object) -> dict[str, object]:
    doc: dict[str, object] = {
        "landmarks": [{"id": 1, "x": 0.0, "y": 0.0}],
        "robots": [{"name": "r", "start": [0, 0, 0], "route": {"steps": [{"wait": 1}]}}],
    }
    doc.update(extra)
    return doc


def test_the_wide_radtan_lens_is_the_issue_s_lens() -> None:
    cam = wide_angle_camera("wide_radtan")
    assert (cam.width, cam.height, cam.distortion_model) == (640, 480, "radial-tangential")
    assert cam.fu == pytest.approx(300.0)
    np.testing.assert_allclose(cam.distortion[:2], [-0.28, 0.07])
    assert cam.invertible
    assert math.degrees(cam.max_angle_rad) > 55  # a wide lens: the corners are far out


@pytest.mark.parametrize("level", ["realistic", "poor"])
def test_calibration_error_levels_are_drawn_at_their_size(level: str) -> None:
    nominal = wide_angle_camera("wide_radtan")
    bound = CALIBRATION_LEVELS[level]
    for seed in range(20):
        true = miscalibrated_camera(nominal, bound, np.random.default_rng(seed))
        rel_f = abs(true.fu / nominal.fu - 1)
        assert 0.5 * bound.focal_rel - 1e-12 <= rel_f <= bound.focal_rel + 1e-12
        for c, c0 in ((true.cu, nominal.cu), (true.cv, nominal.cv)):
            assert 0.5 * bound.principal_px - 1e-9 <= abs(c - c0) <= bound.principal_px + 1e-9
        rel_d = np.abs(true.distortion / nominal.distortion - 1)
        assert np.all(rel_d >= 0.5 * bound.distortion_rel - 1e-9)
        assert np.all(rel_d <= bound.distortion_rel + 1e-9)
        np.testing.assert_allclose(true.T_body_camera, nominal.T_body_camera)  # no mount error
    a = miscalibrated_camera(nominal, bound, np.random.default_rng(1))
    b = miscalibrated_camera(nominal, bound, np.random.default_rng(1))
    other = miscalibrated_camera(nominal, bound, np.random.default_rng(2))
    assert a.fu == b.fu and a.cu == b.cu and a.fu != other.fu  # drawn per seed


def test_no_calibration_error_is_the_nominal_camera() -> None:
    nominal = wide_angle_camera("fisheye")
    true = miscalibrated_camera(nominal, CALIBRATION_LEVELS["none"], np.random.default_rng(0))
    assert (true.fu, true.fv, true.cu, true.cv) == (nominal.fu, nominal.fv, nominal.cu, nominal.cv)
    np.testing.assert_array_equal(true.distortion, nominal.distortion)


def test_calibration_error_in_a_scenario_file() -> None:
    def camera(value: object) -> object:
        doc = _doc()
        doc["robots"][0]["camera"] = {"calibration_error": value}  # type: ignore[index]
        return scenario_from_dict(doc, source="s.yaml").robots[0].camera.calibration_error

    assert camera("realistic") == CALIBRATION_LEVELS["realistic"]
    assert camera(False) is False and camera(True) is True
    got = camera({"focal_rel": 0.001, "mount_deg": 0.1})
    assert got == CalibrationError(focal_rel=0.001, mount_rad=math.radians(0.1))
    with pytest.raises(ValueError, match=r"robots\[0\]\.camera\.calibration_error: expected"):
        camera("awful")


def test_irregular_grid_and_uneven_ceiling_follow_the_layout_seed() -> None:
    def landmarks(seed: int) -> np.ndarray:
        doc = _doc(
            landmarks=[{"id": 1, "x": 9.0, "y": 9.0, "z": 3.0}],
            landmark_grid={"first_id": 10, "x0": 0, "y0": 0, "nx": 5, "ny": 4, "spacing_m": 1.0,
                           "jitter_m": 0.3},
            ceiling_unevenness_m=0.12, layout_seed=seed,
        )  # fmt: skip
        sc = scenario_from_dict(doc, source="s.yaml")
        return np.array([[lm.id, lm.x, lm.y, lm.z] for lm in sc.landmarks])

    a, b, c = landmarks(1), landmarks(1), landmarks(2)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a[1:, 1:3], c[1:, 1:3])
    np.testing.assert_array_equal(a[0], [1, 9.0, 9.0, 3.0])  # its own z is kept
    ids = a[1:, 0].astype(int) - 10
    dx, dy = a[1:, 1] - ids % 5, a[1:, 2] - ids // 5
    assert np.abs(dx).max() <= 0.3 and np.abs(dy).max() <= 0.3 and np.abs(dx).max() > 0.1
    dz = a[1:, 3] - 2.5
    assert np.abs(dz).max() <= 0.12 and np.abs(dz).max() > 0.06


def _robot(route: Route, **kw: object) -> SimRobot:
    odo = OdometryModel(rate_hz=50, wheel_scale=(1.0, 1.0), wheel_base_true_m=0.36, noise_rel=0.0)
    args: dict[str, object] = dict(start=(0.0, 0.0, 0.0), route=route, odometry=odo,
                                   camera_rate_hz=30, frame_drop=0.0, bumps=(),
                                   rng=np.random.default_rng(0))  # fmt: skip
    args.update(kw)
    return SimRobot("r", **args)  # type: ignore[arg-type]


def test_turning_in_place_at_3_rad_s_right_after_driving() -> None:
    limits = DriveLimits(max_omega_radps=3.0, accel_mps2=20.0, distance_gain=20.0)
    robot = _robot(Route((Goto(1.5, 0.0, 1.5), TurnTo(math.pi / 2 + 1.0))), limits=limits)
    odo = [e for e in robot.advance_to(5_000_000_000) if isinstance(e, OdometryMeasured)]
    v = np.array([(e.v_left + e.v_right) / 2 for e in odo])
    w = np.array([(e.v_right - e.v_left) / 0.36 for e in odo])
    assert v.max() == pytest.approx(1.5, abs=1e-9)
    assert w.max() == pytest.approx(3.0, abs=1e-9)
    k = int(np.argmax(w > 2.9))  # the first sample of the fast turn
    assert v[k] == 0.0 and v[k - 3 : k].max() > 0.0  # stopped within a few samples
    assert robot.theta == pytest.approx(math.pi / 2 + 1.0, abs=0.005)


def test_a_kidnap_carries_the_robot_with_its_wheels_still() -> None:
    route = Route((Wait(0.2), Kidnap(2.0, 1.0, 1.5, carry_s=1.0, lift_m=0.4), Wait(1.0)))
    robot = _robot(route)
    items = robot.advance_to(2_000_000_000)
    ((picked, dropped),) = robot.kidnaps
    assert picked == pytest.approx(0.22e9, abs=0.03e9) and dropped - picked == pytest.approx(
        1e9, abs=0.03e9
    )
    assert (robot.x, robot.y, robot.theta) == pytest.approx((2.0, 1.0, 1.5))
    assert all(e.v_left == 0 == e.v_right for e in items if isinstance(e, OdometryMeasured))
    frames = [f for f in items if isinstance(f, FramePose)]
    lifts = [f.T_world_body[2, 3] for f in frames if picked < f.t_ns < dropped]
    assert max(lifts) == pytest.approx(0.4, abs=0.01)
    assert frames[-1].T_world_body[2, 3] == 0.0


def test_wheel_slip_moves_the_body_less_than_the_encoders_count() -> None:
    patch = SlipPatch(0.0, 0.0, radius_m=10.0, slip=(0.2, 0.2))
    robot = _robot(Route((Drive(1.0, 0.5, 0.0),)), slips=(patch,))
    odo = [e for e in robot.advance_to(1_000_000_000) if isinstance(e, OdometryMeasured)]
    counted = sum((e.v_left + e.v_right) / 2 for e in odo) / 50
    assert robot.x == pytest.approx(0.8 * counted, rel=0.03)
    assert counted == pytest.approx(0.5, rel=0.03)


def test_floor_tilt_is_a_plane_rising_towards_its_direction() -> None:
    tilt = FloorTilt(1.0, 1.0, math.radians(1.0), math.radians(90.0))
    h, gx, gy = floor_height((tilt,), 3.0, 2.0)
    assert h == pytest.approx(math.tan(math.radians(1.0)))
    assert (gx, gy) == pytest.approx((0.0, math.tan(math.radians(1.0))))


def test_a_dead_led_stays_dark_while_its_radio_answers() -> None:
    from sim.build import build_world

    doc = _doc(landmarks=[{"id": 1, "x": 0, "y": 0}, {"id": 2, "x": 1, "y": 0, "led_dead": True}])
    world = build_world(scenario_from_dict(doc, source="s.yaml"), np.random.default_rng(0))
    p, _ = world.point_sources(np.array([0.0, 0.0, 0.3]))
    assert len(p) == 1 and p[0][0] == pytest.approx(0.0)
    assert world.landmarks[2].reachable


def test_scenario_errors_name_the_new_fields() -> None:
    bad = _doc(slip_patches=[{"x": 0, "y": 0, "radius_m": 1, "slip": [0.95, 0]}])
    with pytest.raises(ValueError, match=r"slip_patches\[0\]\.slip: each slip must be in"):
        scenario_from_dict(bad, source="s.yaml")
    doc = _doc()
    doc["robots"][0]["route"] = {"steps": [{"kidnap": {"to": [1, 2]}}]}  # type: ignore[index]
    with pytest.raises(
        ValueError, match=r"route\.steps\[0\]\.kidnap\.to: expected \[x, y, theta_deg\]"
    ):
        scenario_from_dict(doc, source="s.yaml")
