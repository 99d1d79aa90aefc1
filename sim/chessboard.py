"""Synthetic photos of a calibration board (chessboard or ChArUco) through a `CameraModel`.

Ray casting: for every output pixel (supersampled `supersample` x `supersample` times) the
ray from `localizer.camera.rays_from_pixels` is intersected with the board plane and the
board texture is sampled there (bilinear); the subsamples are averaged (anti-aliasing), then
a Gaussian blur and sensor noise are added. Both lens models work, including a fisheye beyond
what a pinhole could show. The rays depend only on the camera, so a `BoardRenderer` computes
them once and renders many board poses.
"""

from __future__ import annotations

import math
from typing import Protocol

import cv2
import numpy as np

from localizer.camera import CameraModel, rays_from_pixels
from localizer.types import FloatArray, ImageU8


class BoardSpec(Protocol):
    """The calibration board as rendered here (`calibration.board.BoardSpec` is one; sim
    does not import calibration)."""

    @property
    def pattern(self) -> tuple[int, int]: ...
    @property
    def square_m(self) -> float: ...
    @property
    def kind(self) -> str: ...
    def object_points(self) -> FloatArray: ...
    def charuco_board(self) -> cv2.aruco.CharucoBoard: ...


def board_texture(board: BoardSpec, *, px_per_square: int = 32) -> tuple[ImageU8, float]:
    """The board's printed face with a one-square white margin.

    Args:
        board: the board.
        px_per_square: texture pixels per square.

    Returns:
        (texture uint8 (H, W), offset_squares): board point (x, y) in metres lies at texture
        pixel ((x / square_m + offset_squares) * px_per_square - 0.5, same for y).
    """
    cols, rows = board.pattern[0] + 1, board.pattern[1] + 1  # squares
    if board.kind == "charuco":
        face = board.charuco_board().generateImage(
            (cols * px_per_square, rows * px_per_square), marginSize=0, borderBits=1
        )
        origin_squares = 0.0  # ChArUco corners are measured from the outer board corner
    else:
        ij = np.add.outer(np.arange(rows), np.arange(cols)) % 2
        face = np.where(ij == 0, 0, 255).astype(np.uint8)
        face = np.kron(face, np.ones((px_per_square, px_per_square), np.uint8))
        origin_squares = 1.0  # chessboard corner 0 is the first inner corner
    margin = px_per_square
    texture = cv2.copyMakeBorder(
        face, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255
    )
    return np.ascontiguousarray(texture, dtype=np.uint8), origin_squares + 1.0


def board_centre(board: BoardSpec) -> FloatArray:
    """Middle of the board's corners on the board plane, metres, shape (3,)."""
    pts = board.object_points()
    if board.kind == "charuco":
        pts = pts + np.array([board.square_m, board.square_m, 0.0])
    centre: FloatArray = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return centre


def board_pose_facing(
    camera: CameraModel,
    board: BoardSpec,
    pixel: tuple[float, float],
    distance_m: float,
    *,
    tilt_xy_rad: tuple[float, float] = (0.0, 0.0),
    roll_rad: float = 0.0,
) -> FloatArray:
    """A board pose `T_camera_board` with the board's centre seen at `pixel`.

    The board faces the camera square-on along that ray, then is tilted about its x and y
    axes and rolled about its normal.

    Args:
        pixel: where the board centre appears, (col, row).
        distance_m: camera-to-board-centre distance, metres.

    Returns:
        shape (4, 4).
    """
    ray = rays_from_pixels(camera, np.array([pixel], dtype=np.float64))[0]
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, ray)
    angle = math.atan2(float(np.linalg.norm(axis)), float(ray @ z))
    rvec = axis / max(float(np.linalg.norm(axis)), 1e-12) * angle
    R0 = cv2.Rodrigues(rvec)[0]
    Rt = cv2.Rodrigues(np.array([tilt_xy_rad[0], 0.0, 0.0]))[0]
    Rt = Rt @ cv2.Rodrigues(np.array([0.0, tilt_xy_rad[1], 0.0]))[0]
    Rr = cv2.Rodrigues(np.array([0.0, 0.0, roll_rad]))[0]
    R = R0 @ Rt @ Rr
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = distance_m * ray - R @ board_centre(board)
    return T


class BoardRenderer:
    """Renders one board through one camera at any pose.

    Args:
        camera: the camera (its lens model and intrinsics; the mounting is not used).
        board: the board.
        px_per_square: texture resolution.
        supersample: subsamples per pixel along each axis (anti-aliasing).
    """

    def __init__(
        self,
        camera: CameraModel,
        board: BoardSpec,
        *,
        px_per_square: int = 32,
        supersample: int = 3,
    ) -> None:
        if supersample < 1:
            raise ValueError(f"supersample must be >= 1, got {supersample}")
        self.camera = camera
        self.board = board
        self.supersample = supersample
        self.px_per_square = px_per_square
        self.texture, self._offset_squares = board_texture(board, px_per_square=px_per_square)
        ss = supersample
        sub = (np.arange(ss) + 0.5) / ss - 0.5
        cols = (np.arange(camera.width)[:, None] + sub[None, :]).reshape(-1)
        rows = (np.arange(camera.height)[:, None] + sub[None, :]).reshape(-1)
        cc, rr = np.meshgrid(cols, rows)
        grid = np.column_stack([cc.reshape(-1), rr.reshape(-1)])
        rays = rays_from_pixels(camera, grid)
        self._rays = rays.reshape(camera.height * ss, camera.width * ss, 3).astype(np.float32)

    def render(
        self,
        T_camera_board: FloatArray,
        *,
        rng: np.random.Generator,
        blur_sigma_px: float = 0.6,
        noise_sigma: float = 2.0,
        background: float = 110.0,
        contrast: tuple[float, float] = (30.0, 220.0),
    ) -> ImageU8:
        """One 8-bit gray photo of the board at `T_camera_board` (board -> camera, (4, 4)).

        Args:
            rng: noise generator.
            blur_sigma_px: Gaussian blur (optics, focus), pixels; 0 for none.
            noise_sigma: sensor noise, gray levels.
            background: gray level around the board.
            contrast: gray levels of the board's black and white.
        """
        R = np.asarray(T_camera_board[:3, :3], dtype=np.float32)
        t = np.asarray(T_camera_board[:3, 3], dtype=np.float32)
        normal = R[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = float(normal @ t) / (self._rays @ normal)
            p_board = (self._rays * s[..., None] - t) @ R  # R^T (s d - t)
        scale = self.px_per_square / self.board.square_m
        off = self._offset_squares * self.px_per_square - 0.5
        map_u = (p_board[..., 0] * scale + off).astype(np.float32)
        map_v = (p_board[..., 1] * scale + off).astype(np.float32)
        hit = (s > 0) & np.isfinite(map_u) & np.isfinite(map_v)
        map_u[~hit] = -1e4
        map_v[~hit] = -1e4
        lo, hi = contrast
        tex = (lo + (hi - lo) * (self.texture.astype(np.float32) / 255.0)).astype(np.float32)
        sampled = cv2.remap(
            tex,
            map_u,
            map_v,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=background,
        )
        ss = self.supersample
        h, w = self.camera.height, self.camera.width
        img = sampled.reshape(h, ss, w, ss).mean(axis=(1, 3))
        if blur_sigma_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur_sigma_px)
        img = img + rng.normal(0.0, noise_sigma, img.shape)
        out: ImageU8 = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        return out
