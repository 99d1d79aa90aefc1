"""Synthetic board photos: the corners appear where the lens model projects them."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.board import BoardSpec, find_board
from localizer.camera import pixels_from_points_camera
from localizer.geometry import transform_points
from sim.cameras import wide_angle_camera
from sim.chessboard import BoardRenderer, board_centre, board_pose_facing, board_texture


@pytest.mark.parametrize("lens", ["fisheye", "pinhole"])
def test_found_corners_lie_on_the_projected_board_corners(lens: str) -> None:
    camera = wide_angle_camera(lens)  # type: ignore[arg-type]
    board = BoardSpec((9, 6), 0.02)
    renderer = BoardRenderer(camera, board, supersample=2)
    rng = np.random.default_rng(0)
    for k, pixel in enumerate([(320, 240), (150, 120), (480, 350)]):
        T = board_pose_facing(camera, board, pixel, 0.35, tilt_xy_rad=(0.3, -0.4), roll_rad=k)
        found = find_board(renderer.render(T, rng=rng, noise_sigma=1.0), board)
        assert found is not None
        expected, valid = pixels_from_points_camera(
            camera, transform_points(T, board.object_points())
        )
        assert valid.all()
        err = np.linalg.norm(found.image_points - expected, axis=1)
        if err.mean() > 50:  # the detector may number the corners from the other end
            err = np.linalg.norm(found.image_points[::-1] - expected, axis=1)
        assert err.max() < 0.15


def test_board_pose_puts_the_centre_at_the_pixel() -> None:
    camera = wide_angle_camera("fisheye")
    board = BoardSpec((9, 6), 0.025)
    T = board_pose_facing(camera, board, (100.0, 380.0), 0.5, tilt_xy_rad=(0.2, 0.1))
    centre_camera = transform_points(T, board_centre(board)[None])
    np.testing.assert_allclose(np.linalg.norm(centre_camera), 0.5)
    np.testing.assert_allclose(
        pixels_from_points_camera(camera, centre_camera)[0], [[100, 380]], atol=1e-6
    )


def test_texture_has_the_board_squares_and_a_white_margin() -> None:
    texture, offset = board_texture(BoardSpec((9, 6), 0.025), px_per_square=10)
    assert texture.shape == (90, 120)  # 7 x 10 squares plus a one-square margin
    assert offset == 2.0
    assert texture[:10].min() == 255 and texture[15, 15] == 0 and texture[15, 25] == 255
