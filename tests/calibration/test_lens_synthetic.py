"""Lens calibration on synthetic board photos of the virtual site's cameras: the true
intrinsics are known, so the recovered ones are checked against them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from calibration.board import BoardSpec
from calibration.lens import calibrate_lens
from localizer.camera import CameraModel, pixels_from_points_camera
from sim.cameras import wide_angle_camera
from sim.chessboard import BoardRenderer, board_pose_facing

# where the board centre appears: the middle, the corners and the edges of the image
PIXELS = [
    (320, 240), (150, 120), (490, 120), (150, 360), (490, 360), (320, 100), (320, 380),
    (120, 240), (520, 240), (200, 180), (440, 300), (440, 180), (200, 300),
]  # fmt: skip


def _true_camera(lens: str) -> CameraModel:
    """The virtual site's wide-angle camera with an off-centre principal point."""
    return dataclasses.replace(wide_angle_camera(lens), cu=326.3, cv=236.8)  # type: ignore[arg-type]


def _photos(
    camera: CameraModel,
    board: BoardSpec,
    pixels: list[tuple[int, int]],
    seed: int,
    *,
    distance_m: float = 0.33,
    px_per_square: int = 32,
) -> list[np.ndarray]:
    renderer = BoardRenderer(camera, board, supersample=2, px_per_square=px_per_square)
    rng = np.random.default_rng(seed)
    return [
        renderer.render(
            board_pose_facing(
                camera,
                board,
                p,
                distance_m + 0.04 * (k % 3),
                tilt_xy_rad=(0.45 * np.sin(2 * k), 0.45 * np.cos(1.3 * k)),
                roll_rad=0.25 * k,
            ),
            rng=rng,
        )
        for k, p in enumerate(pixels)
    ]


@pytest.mark.parametrize("lens", ["fisheye", "pinhole"])
def test_recovers_the_true_intrinsics(lens: str) -> None:
    camera = _true_camera(lens)
    board = BoardSpec((9, 6), 0.02)
    result = calibrate_lens(_photos(camera, board, PIXELS, seed=3), model=lens, board=board)  # type: ignore[arg-type]
    got = result.camera
    assert result.used_views == len(PIXELS)
    assert got.distortion_model == camera.distortion_model
    np.testing.assert_allclose([got.fu, got.fv], [camera.fu, camera.fv], rtol=0.005)
    np.testing.assert_allclose([got.cu, got.cv], [camera.cu, camera.cv], atol=1.0)
    # the lens itself: the same pixel for rays up to 50 deg off the axis
    assert result.rms_px < 0.1
    angles = np.radians(np.linspace(0, 50, 6))
    p_cam = np.column_stack([np.sin(angles), np.zeros(6), np.cos(angles)])
    np.testing.assert_allclose(
        pixels_from_points_camera(got, p_cam)[0],
        pixels_from_points_camera(camera, p_cam)[0],
        atol=0.5,
    )


def test_charuco_uses_boards_cut_by_the_image_edge() -> None:
    camera = _true_camera("fisheye")
    board = BoardSpec((9, 6), 0.03, kind="charuco", marker_m=0.0225, dictionary="DICT_4X4_100")
    # boards centred near the border: parts of them fall outside the image
    edge = [(40, 240), (600, 240), (320, 30), (320, 450), (60, 60), (580, 420)]
    photos = _photos(camera, board, PIXELS[:8] + edge, seed=5, distance_m=0.4, px_per_square=48)
    result = calibrate_lens(photos, model="fisheye", board=board)
    partial = [v.corners for v in result.views[8:]]
    assert all(v.used for v in result.views)
    assert any(0 < c < 54 for c in partial)
    got = result.camera
    np.testing.assert_allclose([got.fu, got.fv], [camera.fu, camera.fv], rtol=0.005)
    np.testing.assert_allclose([got.cu, got.cv], [camera.cu, camera.cv], atol=1.0)
    assert result.coverage.outer_fraction > 0.6
    assert [w.split(";")[0] for w in result.warnings] == ["only 14 photos given"]  # no other


def test_boards_only_in_the_middle_warn_about_the_outer_band() -> None:
    camera = _true_camera("fisheye")
    board = BoardSpec((9, 6), 0.02)
    middle = [(320, 240), (280, 210), (360, 270), (300, 260), (340, 220)]
    result = calibrate_lens(_photos(camera, board, middle, seed=7), model="fisheye", board=board)
    assert result.coverage.outer_fraction < 0.5
    assert len(result.warnings) == 2
    assert result.warnings[0].startswith("only 5 photos given")
    assert "outer band" in result.warnings[1] and "wide-angle" in result.warnings[1]
