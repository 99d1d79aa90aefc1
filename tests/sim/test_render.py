from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from sim.cameras import LENSES, wide_angle_camera
from sim.render import (
    ExtendedSource,
    RenderConfig,
    disc_outline,
    render_frame,
)

QUIET = RenderConfig(noise_sigma_counts=0.0, background_counts=0.0)


def _centroid(image: np.ndarray, center: np.ndarray, half: int = 8) -> np.ndarray:
    c, r = round(center[0]), round(center[1])
    patch = image[r - half : r + half + 1, c - half : c + half + 1].astype(np.float64)
    rows, cols = np.mgrid[r - half : r + half + 1, c - half : c + half + 1]
    return np.array([(patch * cols).sum(), (patch * rows).sum()]) / patch.sum()


@pytest.mark.parametrize("lens", LENSES)
def test_spot_centroid_lies_on_projected_pixel(lens: str) -> None:
    mount = T_body_camera_upward(yaw=0.4, offset_xy=(0.12, -0.05), tilt_xy=(0.02, -0.01))
    camera = wide_angle_camera(lens, T_body_camera=mount)  # type: ignore[arg-type]
    rng = np.random.default_rng(7)
    T = T_world_body_from_pose(0.3, -0.2, 0.9)
    # Sources spread over the whole field of view, one per frame so spots do not overlap.
    checked = 0
    for _ in range(40):
        p = np.array([[*rng.uniform(-2.5, 2.5, 2), rng.uniform(2.3, 2.7)]])
        px, valid = predict_pixels(camera, T, p)
        u, v = px[0]
        if not valid[0] or not (10 < u < camera.width - 11 and 10 < v < camera.height - 11):
            continue
        # No angular fall-off: every test spot well exposed (8-bit rounding of a faint spot
        # moves its centroid by more than the tolerance).
        cfg = dataclasses.replace(QUIET, falloff_exponent=0.0)
        image = render_frame(camera, T, p, [0.8], rng=None, config=cfg)
        assert image.max() < 255, "test spot must not saturate"
        np.testing.assert_allclose(_centroid(image, px[0]), px[0], atol=0.05)
        checked += 1
    assert checked >= 15


def test_spot_brightness_falls_with_angle_and_distance() -> None:
    camera = wide_angle_camera("pinhole")
    T = np.eye(4)
    sources = np.array([[0.0, 0.0, 2.5], [1.8, 0.0, 2.5], [0.0, 0.0, 4.0]])
    peaks = []
    for s in sources:
        image = render_frame(camera, T, s[None], [1.0], rng=None, config=QUIET)
        peaks.append(float(image.max()))
    assert peaks[0] > 1.5 * peaks[1] > 0
    assert peaks[0] > 2.0 * peaks[2] > 0


def test_nominal_led_on_axis_has_nominal_peak() -> None:
    camera = wide_angle_camera("pinhole")
    cfg = RenderConfig(noise_sigma_counts=0.0, background_counts=0.0, peak_counts=150.0)
    # Camera 0.3 m above the floor; LED 2.5 m above the optical centre, exactly on axis.
    cam = dataclasses.replace(camera, cu=320.0, cv=240.0)
    image = render_frame(cam, np.eye(4), [[0.0, 0.0, 2.8]], [1.0], rng=None, config=cfg)
    assert image[240, 320] == pytest.approx(150, abs=1)


def test_bright_source_saturates_and_noise_is_seeded() -> None:
    camera = wide_angle_camera("fisheye")
    cfg = RenderConfig()
    args = (camera, np.eye(4), [[0.0, 0.0, 2.5]], [20.0])
    a = render_frame(*args, rng=np.random.default_rng(3), config=cfg)
    b = render_frame(*args, rng=np.random.default_rng(3), config=cfg)
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.uint8 and a.shape == (480, 640)
    assert int((a == 255).sum()) >= 9
    corner = a[:100, :100].astype(np.float64)
    assert corner.mean() == pytest.approx(cfg.background_counts, abs=0.3)
    assert corner.std() == pytest.approx(cfg.noise_sigma_counts, rel=0.1)


def test_sources_outside_view_or_dark_are_not_drawn() -> None:
    camera = wide_angle_camera("pinhole")
    image = render_frame(
        camera, np.eye(4), [[0, 0, -1.0], [30.0, 0, 2.5], [0, 0, 2.5]], [1, 1, 0],
        rng=None, config=QUIET,
    )  # fmt: skip
    assert image.max() == 0


def test_extended_lamp_is_a_saturated_disc() -> None:
    camera = wide_angle_camera("pinhole")
    lamp = ExtendedSource(disc_outline([0.5, 0.3, 2.5], 0.12), 600.0, "halogen lamp")
    image = render_frame(camera, np.eye(4), np.zeros((0, 3)), [], rng=None, extended=[lamp])
    (px,), _ = predict_pixels(camera, np.eye(4), [[0.5, 0.3, 2.5]])
    assert image[round(px[1]), round(px[0])] == 255
    saturated = int((image == 255).sum())
    # disc radius ~ f * 0.12 / 2.5 ~ 15 px: area ~ 700 px
    assert 400 < saturated < 1100


def test_render_rejects_mismatched_intensities() -> None:
    with pytest.raises(ValueError, match="intensities"):
        render_frame(wide_angle_camera("pinhole"), np.eye(4), [[0, 0, 2.5]], [1, 2], rng=None)


def test_overlapping_spots_add_up_and_noisy_frames_keep_the_spot() -> None:
    camera = wide_angle_camera("pinhole")
    T = np.eye(4)
    a, b = [0.0, 0.0, 2.5], [0.004, 0.0, 2.5]  # ~0.5 px apart
    cfg = dataclasses.replace(QUIET, peak_counts=60.0)
    both = render_frame(camera, T, [a, b], [1.0, 1.0], rng=None, config=cfg).astype(int)
    one = render_frame(camera, T, [a], [1.0], rng=None, config=cfg).astype(int)
    two = render_frame(camera, T, [b], [1.0], rng=None, config=cfg).astype(int)
    np.testing.assert_allclose(both, one + two, atol=1)
    noisy = render_frame(camera, T, [a], [1.0], rng=np.random.default_rng(1))
    (px,), _ = predict_pixels(camera, T, [a])
    centroid = _centroid(noisy.astype(np.float64) - RenderConfig().background_counts, px, half=4)
    np.testing.assert_allclose(centroid, px, atol=0.15)
