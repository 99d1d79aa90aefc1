from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from localizer.camera import (
    CameraModel,
    T_body_camera_upward,
    bearings_body_from_pixels,
    camera_from_sensor,
    normalized_from_pixels,
    pixels_from_points_camera,
    predict_pixels,
    rays_from_pixels,
    sensor_from_camera,
)
from localizer.geometry import T_world_body_from_pose, transform_points
from tests.localizer.cameras import make_camera

LENSES = ("radial-tangential", "equidistant")


def pixel_grid(cam: CameraModel, margin: float) -> np.ndarray:
    cols = np.linspace(margin, cam.width - 1 - margin, 17)
    rows = np.linspace(margin, cam.height - 1 - margin, 13)
    return np.array([(c, r) for c in cols for r in rows])


@pytest.mark.parametrize("model", LENSES)
def test_pixel_ray_pixel_round_trip(model: str) -> None:
    cam = make_camera(model)
    px = pixel_grid(cam, 20.0)
    rays = rays_from_pixels(cam, px)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-12)
    back, valid = pixels_from_points_camera(cam, rays * 2.2)  # any depth along the ray
    assert valid.all()
    np.testing.assert_allclose(back, px, atol=1e-6)


@pytest.mark.parametrize("model", LENSES)
def test_normalised_coordinates_are_the_rays_over_their_depth(model: str) -> None:
    cam = make_camera(model)
    px = pixel_grid(cam, 40.0)
    rays = rays_from_pixels(cam, px)
    np.testing.assert_allclose(
        normalized_from_pixels(cam, px), rays[:, :2] / rays[:, 2:], atol=1e-12
    )
    # the principal point looks along the optical axis
    np.testing.assert_allclose(
        rays_from_pixels(cam, [[cam.cu, cam.cv]]), [[0.0, 0.0, 1.0]], atol=1e-12
    )


def test_wide_angle_lens_bends_rays_off_the_pinhole_line() -> None:
    cam = make_camera("radial-tangential")
    corner = normalized_from_pixels(cam, [[10.0, 10.0]])[0]
    pinhole = (np.array([10.0, 10.0]) - (cam.cu, cam.cv)) / (cam.fu, cam.fv)
    assert np.linalg.norm(corner) > 1.2 * np.linalg.norm(pinhole)  # barrel distortion


def test_points_behind_outside_the_view_or_the_image_are_invalid() -> None:
    cam = make_camera("equidistant")
    p = np.array(
        [
            [0.0, 0.0, 1.0],  # straight ahead: valid
            [0.0, 0.0, -1.0],  # behind
            [1.0, 0.0, 1e-12],  # on the image plane's horizon
            [50.0, 0.0, 1.0],  # 89 deg off axis: outside the lens's field of view
        ]
    )
    # inside the lens's cone (which reaches the image corners) but beyond the image's edge
    edge = math.acos(rays_from_pixels(cam, [[cam.width - 0.5, cam.cv]])[0, 2])
    assert edge < 0.95 * cam.max_angle_rad
    beyond = 0.5 * (edge + cam.max_angle_rad)
    p = np.vstack([p, [math.sin(beyond), 0.0, math.cos(beyond)]])
    px, valid = pixels_from_points_camera(cam, p)
    np.testing.assert_array_equal(valid, [True, False, False, False, False])
    np.testing.assert_allclose(px[0], [cam.cu, cam.cv], atol=1e-9)
    assert pixels_from_points_camera(cam, np.zeros((0, 3)))[0].shape == (0, 2)


def test_upward_mounting_shows_the_robot_front_at_the_image_top() -> None:
    cam = make_camera("radial-tangential")
    T_wb = T_world_body_from_pose(0.0, 0.0, 0.0)
    ahead, left = [[0.5, 0.0, 2.5]], [[0.0, 0.5, 2.5]]
    (px_ahead,), _ = predict_pixels(cam, T_wb, ahead)
    (px_left,), _ = predict_pixels(cam, T_wb, left)
    # (within 0.05 px: the lens's tangential terms bend the axes a little)
    assert px_ahead[1] < cam.cv - 50 and abs(px_ahead[0] - cam.cu) < 0.05  # up in the image
    assert px_left[0] > cam.cu + 50 and abs(px_left[1] - cam.cv) < 0.05  # image right
    # the body's up direction is the optical axis
    np.testing.assert_allclose(
        bearings_body_from_pixels(cam, [[cam.cu, cam.cv]]), [[0.0, 0.0, 1.0]], atol=1e-12
    )


def test_mounting_offset_and_yaw() -> None:
    T = T_body_camera_upward(yaw=math.pi / 2, offset_xy=(0.1, -0.05), height=0.4)
    cam = make_camera("equidistant", T)
    np.testing.assert_allclose(T[:3, 3], [0.1, -0.05, 0.4])
    # the point straight above the optical centre lands on the principal point
    T_wb = T_world_body_from_pose(2.0, 1.0, 0.7)
    above = transform_points(T_wb, np.array([[0.1, -0.05, 2.6]]))
    (px,), valid = predict_pixels(cam, T_wb, above)
    assert valid[0]
    np.testing.assert_allclose(px, [cam.cu, cam.cv], atol=1e-6)
    # yawed 90 deg: the image's right (camera x) now points to the robot's back (body -x)
    np.testing.assert_allclose(T[:3, 0], [-1.0, 0.0, 0.0], atol=1e-12)
    bearing = bearings_body_from_pixels(cam, [[cam.cu + 100.0, cam.cv]])[0]
    assert bearing[0] < -0.2 and abs(bearing[1]) < 1e-9


def test_mounting_tilt_tips_the_optical_axis() -> None:
    T = T_body_camera_upward(tilt_xy=(0.02, -0.03))
    axis = T[:3, 2]
    np.testing.assert_allclose(np.linalg.norm(axis), 1.0)
    assert math.degrees(math.acos(axis[2])) == pytest.approx(
        math.degrees(math.hypot(0.02, 0.03)), rel=1e-3
    )
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)


def sensor_yaml(model: str = "radial-tangential") -> dict[str, Any]:
    return sensor_from_camera(make_camera(model))


@pytest.mark.parametrize("model", LENSES)
def test_sensor_yaml_round_trip(model: str) -> None:
    cam = make_camera(model)
    back = camera_from_sensor(sensor_from_camera(cam))
    assert back.resolution == cam.resolution
    assert (back.fu, back.fv, back.cu, back.cv) == (cam.fu, cam.fv, cam.cu, cam.cv)
    assert back.distortion_model == cam.distortion_model
    np.testing.assert_array_equal(back.distortion, cam.distortion)
    np.testing.assert_array_equal(back.T_body_camera, cam.T_body_camera)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.pop("intrinsics"), "missing field 'intrinsics'"),
        (lambda d: d.update(intrinsics=[300, 300, 320]), "'intrinsics' must be a list of"),
        (lambda d: d.update(intrinsics=[300, "x", 320, 240]), "'intrinsics' must hold numbers"),
        (lambda d: d.update(camera_model="omni"), "camera_model must be 'pinhole'"),
        (lambda d: d.update(distortion_model="fov"), "distortion_model must be one of"),
        (lambda d: d.update(distortion_coefficients=[0.1]), "'distortion_coefficients'"),
        (lambda d: d.update(resolution=[640, 0]), "resolution must be positive"),
        (lambda d: d.update(intrinsics=[-300, 300, 320, 240]), "fu must be a positive number"),
        (lambda d: d.update(T_BS={"rows": 4, "cols": 4, "data": [1.0] * 12}), "T_BS"),
        (lambda d: d.update(T_BS={"rows": 4, "cols": 4, "data": [2.0] * 16}), "T_BS"),
        (lambda d: d.update(rate_hz="fast"), "rate_hz"),
    ],
)
def test_camera_from_sensor_names_the_bad_field(edit: Any, message: str) -> None:
    data = sensor_yaml()
    edit(data)
    with pytest.raises(ValueError, match=r"^rec/cam0/sensor\.yaml: ") as err:
        camera_from_sensor(data, source="rec/cam0/sensor.yaml")
    assert message in str(err.value)


def test_equidistant_wants_four_coefficients() -> None:
    data = sensor_yaml("equidistant")
    data["distortion_coefficients"] = [0.1, 0.0, 0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="equidistant wants 4"):
        camera_from_sensor(data)


def test_camera_from_sensor_rejects_a_non_mapping() -> None:
    with pytest.raises(ValueError, match=r"sensor\.yaml: expected a mapping"):
        camera_from_sensor([1, 2, 3])  # type: ignore[arg-type]


def fold_back_camera() -> CameraModel:
    """Strong barrel distortion whose image reaches past the fold-back radius: the radius
    r_d = r (1 + k1 r^2) peaks at r = 1 / sqrt(-3 k1) = 0.745 (k1 = -0.6), r_d = 0.497,
    i.e. 159 px from the centre with f = 320."""
    return CameraModel(
        640, 480, 320.0, 320.0, 319.5, 239.5, "radial-tangential", np.array([-0.6, 0, 0, 0, 0])
    )


def test_usual_lenses_invert_everywhere() -> None:
    for model in LENSES:
        assert make_camera(model).invertible


def test_pixels_past_a_fold_back_have_no_inverse() -> None:
    cam = fold_back_camera()
    assert not cam.invertible
    r_u = 1.0 / math.sqrt(3 * 0.6)
    r_fold_px = 320.0 * r_u * (1 - 0.6 * r_u**2)
    inside = np.array([[319.5 + r, 239.5] for r in (0.0, 40.0, 0.9 * r_fold_px)])
    outside = np.array([[319.5 + r, 239.5] for r in (1.02 * r_fold_px, 200.0, 320.0)])
    xy = normalized_from_pixels(cam, np.vstack([inside, outside]))
    # inside: the true inverse (OpenCV's value, reprojecting to the pixel)
    back, valid = pixels_from_points_camera(cam, np.column_stack([xy[:3], np.ones(3)]))
    assert valid.all()
    np.testing.assert_allclose(back, inside, atol=1e-6)
    # outside: NaN, not OpenCV's silent pinhole value (u - cu) / fu
    assert np.isnan(xy[3:]).all()
    # the field of view ends before the fold-back angle, past the last pixel that inverts
    assert math.atan(float(np.hypot(*xy[2]))) < cam.max_angle_rad <= math.atan(r_u)


def test_no_fix_from_a_pixel_past_the_fold_back() -> None:
    from localizer.pose import solve_pose

    cam = fold_back_camera()
    P = np.array([[0.0, 0.0, 2.5], [0.5, 0.0, 2.5]])
    assert solve_pose(cam, np.array([[319.5, 239.5], [630.0, 239.5]]), P) is None
