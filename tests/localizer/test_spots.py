"""Spot detection: sub-pixel centroids, filters against lamps and specks, windowed fast path."""

from __future__ import annotations

import numpy as np
import pytest

from localizer.camera import CameraModel, T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.spot_windows import detect_spots_in_windows
from localizer.spots import DetectionConfig, detect_spots, estimate_background, window_boxes
from sim.render import ExtendedSource, RenderConfig, disc_outline, render_frame

CAM = CameraModel(
    640, 480, 300.0, 300.0, 319.5, 239.5, "radial-tangential", np.zeros(5), T_body_camera_upward()
)
LANDMARKS = np.array([[0.6, 0.0, 2.5], [0.0, 0.6, 2.5], [-0.6, -0.3, 2.4]])


def _frame(
    pose: tuple[float, float, float] = (0.1, 0.05, 0.3),
    *,
    extended: tuple[ExtendedSource, ...] = (),
    seed: int = 1,
    sources: np.ndarray = LANDMARKS,
) -> tuple[np.ndarray, np.ndarray]:
    T = T_world_body_from_pose(*pose)
    img = render_frame(
        CAM, T, sources, np.ones(len(sources)), rng=np.random.default_rng(seed), extended=extended
    )
    px, valid = predict_pixels(CAM, T, sources)
    return img, px[valid]


def _match(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    d = np.hypot(found[:, None, 0] - truth[None, :, 0], found[:, None, 1] - truth[None, :, 1])
    out: np.ndarray = d.min(axis=0)
    return out


def test_centroids_are_sub_pixel_accurate() -> None:
    img, truth = _frame()
    spots = detect_spots(img, DetectionConfig())
    assert len(spots) == 3
    np.testing.assert_array_less(_match(spots.pixels, truth), 0.1)
    assert np.all(spots.areas >= 4)
    assert np.all(spots.intensities > 500)


def test_centroid_bias_over_sub_pixel_offsets_is_small() -> None:
    rng = np.random.default_rng(3)
    errors: list[float] = []
    for _ in range(20):
        pose = (rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-np.pi, np.pi))
        img, truth = _frame(pose, seed=int(rng.integers(1000)))
        spots = detect_spots(img, DetectionConfig())
        errors.extend(_match(spots.pixels, truth))
    assert np.mean(errors) < 0.06
    assert np.max(errors) < 0.15


def test_empty_frame_has_no_spots() -> None:
    img = render_frame(CAM, np.eye(4), np.zeros((0, 3)), np.zeros(0), rng=np.random.default_rng(0))
    assert len(detect_spots(img, DetectionConfig())) == 0


def test_lamp_and_sunlight_patch_are_rejected() -> None:
    lamp = ExtendedSource(disc_outline((0.3, 0.5, 2.5), 0.15), 240.0, "lamp")
    sun = ExtendedSource(
        np.array([[-0.9, 0.2, 2.5], [-0.3, 0.2, 2.5], [-0.3, 0.8, 2.5], [-0.9, 0.8, 2.5]]),
        120.0,
        "sunlight",
    )
    img, truth = _frame((0.0, 0.0, 0.0), extended=(lamp, sun))
    spots = detect_spots(img, DetectionConfig())
    assert len(spots) == 3
    np.testing.assert_array_less(_match(spots.pixels, truth), 0.1)


def test_specks_are_rejected() -> None:
    img, _ = _frame()
    img = img.copy()
    img[100, 100] = 255  # a hot pixel
    img[400, 500] = 200
    spots = detect_spots(img, DetectionConfig())
    assert len(spots) == 3


def test_fixed_threshold() -> None:
    img, truth = _frame()
    spots = detect_spots(img, DetectionConfig(threshold_counts=60))
    np.testing.assert_array_less(_match(spots.pixels, truth), 0.15)


def test_background_estimate() -> None:
    img, _ = _frame()
    bg, noise = estimate_background(img, DetectionConfig())
    assert 8 <= bg <= 12
    assert 1.0 <= noise <= 4.0


def test_windows_find_the_same_spots_as_the_full_frame() -> None:
    img, truth = _frame()
    cfg = DetectionConfig()
    full = detect_spots(img, cfg)
    win = detect_spots_in_windows(img, truth + 2.0, np.full((3, 2), 10.0), cfg)
    assert len(win) == 3
    order = np.argsort(win.pixels[:, 0])
    np.testing.assert_allclose(
        win.pixels[order], full.pixels[np.argsort(full.pixels[:, 0])], atol=1e-9
    )


def test_window_missing_a_spot_finds_nothing_and_cut_spots_are_dropped() -> None:
    img, truth = _frame()
    cfg = DetectionConfig()
    assert len(detect_spots_in_windows(img, [[20.0, 20.0]], [[8.0, 8.0]], cfg)) == 0
    # A window whose edge passes through the spot: the biased partial spot is dropped.
    assert len(detect_spots_in_windows(img, [truth[0] + [4.0, 0.0]], [[4.0, 4.0]], cfg)) == 0


def test_overlapping_windows_report_a_spot_once() -> None:
    img, truth = _frame()
    centers = np.array([truth[0] + [3.0, 0.0], truth[0] - [3.0, 1.0]])
    spots = detect_spots_in_windows(img, centers, np.full((2, 2), 12.0), DetectionConfig())
    assert len(spots) == 1
    np.testing.assert_allclose(spots.pixels[0], truth[0], atol=0.1)


def test_spot_at_the_image_border_is_kept() -> None:
    # A landmark whose spot lands 2 px from the right edge.
    T = T_world_body_from_pose(0.0, 0.0, 0.0)
    target = np.array([[637.0, 240.0]])
    from localizer.camera import rays_from_pixels
    from localizer.geometry import transform_points

    ray = rays_from_pixels(CAM, target)[0]
    p_cam = ray * (2.2 / ray[2])
    p_world = transform_points(T @ CAM.T_body_camera, p_cam[None])
    img = render_frame(CAM, T, p_world, np.full(1, 2.0), rng=np.random.default_rng(0))
    cfg = DetectionConfig()
    spots = detect_spots(img, cfg)
    assert len(spots) == 1
    np.testing.assert_allclose(spots.pixels[0], target[0], atol=0.3)
    win = detect_spots_in_windows(img, target, [[10.0, 10.0]], cfg)
    np.testing.assert_allclose(win.pixels, spots.pixels)


def test_window_boxes_merge_and_clip() -> None:
    boxes = window_boxes(
        np.array([[5.0, 5.0], [12.0, 8.0], [100.0, 100.0]]), np.full((3, 2), 5.0), 50, 50
    )
    assert boxes == [(0, 0, 18, 14)]


def test_bad_image_is_rejected() -> None:
    with pytest.raises(ValueError, match="uint8"):
        detect_spots(np.zeros((4, 4), dtype=np.float32), DetectionConfig())
    with pytest.raises(ValueError, match="threshold_counts"):
        DetectionConfig(threshold_counts=300)


def test_saturated_brightest_spot_still_centred() -> None:
    cfg = RenderConfig(peak_counts=400.0)
    T = T_world_body_from_pose(0.0, 0.0, 0.0)
    img = render_frame(CAM, T, LANDMARKS, np.ones(3), rng=np.random.default_rng(2), config=cfg)
    px, _ = predict_pixels(CAM, T, LANDMARKS)
    spots = detect_spots(img, DetectionConfig())
    assert len(spots) == 3
    np.testing.assert_array_less(_match(spots.pixels, px), 0.2)
