"""Calibration boards and finding their corners in one image.

Two kinds of board:
- a plain chessboard, found with `cv2.findChessboardCorners` and refined with
  `cv2.cornerSubPix` (falling back to the slower `cv2.findChessboardCornersSB`, which copes
  better with strong distortion, when `cv2.checkChessboard` sees a board);
- a ChArUco board (`cv2.aruco.CharucoDetector`), whose corners carry IDs, so a board that is
  only partly in view (at the edge of a wide lens) still gives usable corners.

`pattern` is always the number of *inner* corners (where four squares meet), (columns, rows):
a board of 10 x 7 squares has a 9 x 6 pattern.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from localizer.types import FloatArray, ImageU8

BoardKind = Literal["chessboard", "charuco"]

_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)


def parse_pattern(text: str) -> tuple[int, int]:
    """Inner corners from text such as "9x6" (columns x rows).

    Raises:
        ValueError: naming the text when it is not two integers >= 2 joined by "x".
    """
    parts = text.strip().lower().split("x")
    try:
        cols, rows = (int(p) for p in parts)
    except ValueError:
        raise ValueError(
            f"pattern: expected inner corners as COLSxROWS, e.g. 9x6, got {text!r}"
        ) from None
    if cols < 2 or rows < 2:
        raise ValueError(f"pattern: inner corners must be >= 2 each, got {text!r}")
    return cols, rows


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board.

    Attributes:
        pattern: inner corners (columns, rows), each >= 2.
        square_m: side of one square, metres.
        kind: "chessboard" or "charuco".
        marker_m: side of a ChArUco marker, metres (ChArUco only; default 0.75 * square_m).
        dictionary: OpenCV ArUco dictionary name, e.g. "DICT_5X5_100" (ChArUco only).
        min_charuco_corners: fewest ChArUco corners for a view to count.
    """

    pattern: tuple[int, int] = (9, 6)
    square_m: float = 0.025
    kind: BoardKind = "chessboard"
    marker_m: float | None = None
    dictionary: str = "DICT_5X5_100"
    min_charuco_corners: int = 8

    def __post_init__(self) -> None:
        cols, rows = self.pattern
        if int(cols) != cols or int(rows) != rows or cols < 2 or rows < 2:
            raise ValueError(
                f"board pattern: inner corners must be two integers >= 2, got {self.pattern!r}"
            )
        if not np.isfinite(self.square_m) or self.square_m <= 0:
            raise ValueError(f"board square size must be positive metres, got {self.square_m!r}")
        if self.kind not in ("chessboard", "charuco"):
            raise ValueError(f"board kind must be 'chessboard' or 'charuco', got {self.kind!r}")
        if self.kind == "charuco":
            if not hasattr(cv2.aruco, self.dictionary):
                raise ValueError(f"unknown ArUco dictionary {self.dictionary!r}")
            marker = self.marker_size_m
            if not 0 < marker < self.square_m:
                raise ValueError(
                    f"ChArUco marker size must lie between 0 and the square size "
                    f"{self.square_m} m, got {marker!r}"
                )

    @property
    def marker_size_m(self) -> float:
        """Side of a ChArUco marker, metres."""
        return 0.75 * self.square_m if self.marker_m is None else float(self.marker_m)

    @property
    def corner_count(self) -> int:
        """Inner corners on the whole board."""
        return int(self.pattern[0] * self.pattern[1])

    def object_points(self) -> FloatArray:
        """Inner-corner positions on the board plane (z = 0), metres, shape (cols * rows, 3).

        Ordered row by row, as `findChessboardCorners` and the ChArUco corner IDs order them.
        """
        cols, rows = self.pattern
        grid = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2).astype(np.float64)
        return np.column_stack([grid * self.square_m, np.zeros(len(grid))])

    def charuco_board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV ChArUco board (squares = pattern + 1)."""
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        squares = (self.pattern[0] + 1, self.pattern[1] + 1)
        return cv2.aruco.CharucoBoard(squares, self.square_m, self.marker_size_m, dictionary)


@dataclass(frozen=True, eq=False)
class BoardCorners:
    """Corners of the board found in one image.

    Attributes:
        image_points: pixels (col, row), shape (N, 2).
        object_points: the same corners on the board, metres, shape (N, 3).
    """

    image_points: FloatArray
    object_points: FloatArray

    def __len__(self) -> int:
        return len(self.image_points)


def as_gray(image: npt.NDArray[np.generic], name: str = "image") -> ImageU8:
    """An 8-bit single-channel copy of a decoded image (gray, BGR or BGRA; uint8 or uint16)."""
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        img = cv2.cvtColor(img, code)
    if img.ndim != 2 or img.size == 0:
        raise ValueError(f"{name}: expected a gray or colour image, got shape {img.shape}")
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype != np.uint8:
        raise ValueError(f"{name}: expected 8- or 16-bit pixels, got {img.dtype}")
    return np.ascontiguousarray(img)


def find_board(gray: ImageU8, board: BoardSpec) -> BoardCorners | None:
    """Find the board's inner corners in a gray image; None when it is not found.

    A chessboard must be found whole; a ChArUco board counts with at least
    `board.min_charuco_corners` corners.
    """
    if board.kind == "charuco":
        return _find_charuco(gray, board)
    return _find_chessboard(gray, board.pattern, board.object_points())


def _find_chessboard(
    gray: ImageU8, pattern: tuple[int, int], object_points: FloatArray
) -> BoardCorners | None:
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, pattern, flags=flags)
    if found and corners is not None:
        grid = np.asarray(corners, dtype=np.float64).reshape(pattern[1], pattern[0], 2)
        half = _subpix_half_window(grid)
        corners = cv2.cornerSubPix(gray, corners, (half, half), (-1, -1), _SUBPIX_CRITERIA)
    elif cv2.checkChessboard(gray, pattern):  # cheap test: is there a board at all?
        found, corners = cv2.findChessboardCornersSB(
            gray, pattern, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
        )
        if not found or corners is None:
            return None
    else:
        return None
    pts = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if len(pts) != len(object_points):
        return None
    return BoardCorners(image_points=pts, object_points=object_points.copy())


def _subpix_half_window(grid: FloatArray) -> int:
    """Half-size of the `cornerSubPix` window: OpenCV's usual 11 px, but at most half the
    smallest spacing between neighbouring corners (shape (rows, cols, 2)), so that the window
    never reaches the next corner of a small or distant board (a bias of pixels otherwise).
    """
    dx = np.linalg.norm(np.diff(grid, axis=1), axis=2).min()
    dy = np.linalg.norm(np.diff(grid, axis=0), axis=2).min()
    return int(np.clip(np.floor(0.5 * min(dx, dy)), 2, 11))


def _find_charuco(gray: ImageU8, board: BoardSpec) -> BoardCorners | None:
    cv_board = board.charuco_board()
    corners, ids, _, _ = cv2.aruco.CharucoDetector(cv_board).detectBoard(gray)
    if corners is None or ids is None or len(ids) < board.min_charuco_corners:
        return None
    obj, img = cv_board.matchImagePoints(corners, ids)  # type: ignore[call-overload]
    pts = np.asarray(img, dtype=np.float64).reshape(-1, 2)
    obj_pts = np.asarray(obj, dtype=np.float64).reshape(-1, 3)
    # corners on one line fix no homography: demand a spread in both board axes
    if np.ptp(obj_pts[:, 0]) < board.square_m / 2 or np.ptp(obj_pts[:, 1]) < board.square_m / 2:
        return None
    return BoardCorners(image_points=pts, object_points=obj_pts)


def suggest_pattern(gray: ImageU8, pattern: tuple[int, int]) -> tuple[int, int] | None:
    """A nearby inner-corner count that finds a chessboard in `gray`, or None.

    Tries the usual mistakes: squares counted instead of inner corners (one too many each
    way), and off-by-one in one direction. Uses the fast check, so it costs little.
    """
    cols, rows = pattern
    candidates = [
        (cols - 1, rows - 1),
        (cols - 1, rows),
        (cols, rows - 1),
        (cols + 1, rows + 1),
        (cols + 1, rows),
        (cols, rows + 1),
        (cols - 2, rows - 2),
    ]
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    for cand in candidates:
        if min(cand) < 2 or cand == pattern:
            continue
        found, _ = cv2.findChessboardCorners(gray, cand, flags=flags)
        if found:
            return cand
    return None
