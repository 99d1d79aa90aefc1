"""Which landmark is which spot, for the mounting calibration, without knowing the mounting.

The localizer identifies spots through the robot's pose, which needs `T_BS`: the very thing
the mounting calibration measures. This identifier works on the camera's own pose instead:

1. While the robot stands still, the start-up sweep lights one landmark at a time: a frame
   with exactly one lit landmark and exactly one spot names that spot.
2. Once three or more spots are named, the camera's world pose is solved from them
   (`camera_pose_from_landmarks`); the next frame's lit landmarks are predicted from it and
   each spot takes the nearest prediction within `max_jump_px` (the motion between frames);
   the pose is solved again and every spot within `match_px` of a prediction is named.
3. Without a pose yet, named spots are followed from frame to frame by the nearest spot;
   when exactly one lit landmark is still unnamed and exactly one spot is left over, that
   spot is it (identification by elimination: a sweep that stops once all but one landmark
   are named, as the localizer's does, names the last one when all are lit). With two
   named and more left, each way of naming two more of the leftover spots is tried: the
   one whose camera pose fits all four within `max_pose_rms_px`, when no other does, wins.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import permutations

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from calibration.camera_pose import camera_pose_from_landmarks
from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.geometry import invert_transform, transform_points
from localizer.landmark_map import LandmarkMap
from localizer.types import FloatArray

Detection = tuple[int, list[int], FloatArray]


@dataclass(frozen=True)
class IdentifyConfig:
    """Tuning of the identification.

    Attributes:
        max_jump_px: a spot moves at most this far between frames, pixels.
        match_px: after the pose is solved, a spot within this of a prediction is named.
        max_pose_rms_px: a pose whose reprojection RMS exceeds this is not trusted.
        max_hypotheses: most namings of two leftover spots tried in one frame (beyond it,
            the frame names nothing more).
    """

    max_jump_px: float = 25.0
    match_px: float = 3.0
    max_pose_rms_px: float = 2.0
    max_hypotheses: int = 400


def _match(spots: FloatArray, candidates: FloatArray, limit_px: float) -> list[tuple[int, int]]:
    """Pairs (spot index, candidate index) with the least total distance, each within limit."""
    if len(spots) == 0 or len(candidates) == 0:
        return []
    cost = np.linalg.norm(spots[:, None, :] - candidates[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(np.where(cost <= limit_px, cost, 1e6))
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if cost[r, c] <= limit_px]


def identify_spots(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    frames: Iterable[tuple[int, npt.ArrayLike, frozenset[int] | None]],
    *,
    config: IdentifyConfig | None = None,
) -> list[Detection]:
    """Name the spots of each frame.

    Args:
        camera: the calibrated lens (its mounting is not used).
        landmark_map: the landmarks.
        frames: per frame (t_ns, spot pixels (N, 2), lit landmark IDs or None for all lit).

    Returns:
        Per frame with three or more named spots: (t_ns, landmark ids, pixels (N, 2)), the
        input of `mounting_from_observations`.
    """
    cfg = config or IdentifyConfig()
    all_ids = [int(i) for i in landmark_map.ids]
    last_px: dict[int, FloatArray] = {}
    T_camera_world: FloatArray | None = None
    last_centre = np.zeros(3)
    out: list[Detection] = []
    for t_ns, pixels, lit in frames:
        spots = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        lit_ids = all_ids if lit is None else sorted(i for i in lit if i in landmark_map)
        named: dict[int, FloatArray] = {}
        if len(lit_ids) == 1 and len(spots) == 1:
            named[lit_ids[0]] = spots[0]  # the sweep names it
        elif T_camera_world is not None:
            named = _named_by_prediction(
                camera, landmark_map, lit_ids, spots, T_camera_world, cfg.max_jump_px
            )
        else:
            known = [i for i in lit_ids if i in last_px]
            cand = np.array([last_px[i] for i in known]).reshape(-1, 2)
            pairs = _match(spots, cand, cfg.max_jump_px)
            named = {known[c]: spots[s] for s, c in pairs}
            taken = {s for s, _ in pairs}
            named.update(_named_by_elimination(lit_ids, spots, named, taken))
            if len(named) == 2:
                named.update(
                    _named_by_hypothesis(camera, landmark_map, lit_ids, spots, named, taken, cfg)
                )
        if len(named) >= 3:
            ids = list(named)
            pose = camera_pose_from_landmarks(
                camera,
                np.array([named[i] for i in ids]),
                landmark_map.positions[[landmark_map.index_of(i) for i in ids]],
                near_world_m=None if T_camera_world is None else last_centre,
            )
            if pose is not None and pose.residual_rms_px <= cfg.max_pose_rms_px:
                T_camera_world = invert_transform(pose.T_world_camera)
                last_centre = pose.T_world_camera[:3, 3]
                named = _named_by_prediction(
                    camera, landmark_map, lit_ids, spots, T_camera_world, cfg.match_px
                )
            else:
                T_camera_world = None
        last_px.update(named)
        if len(named) >= 3:
            ids = sorted(named)
            out.append((int(t_ns), ids, np.array([named[i] for i in ids])))
    return out


def _named_by_elimination(
    lit_ids: list[int], spots: FloatArray, named: dict[int, FloatArray], taken: set[int]
) -> dict[int, FloatArray]:
    """The one spot left over (not in `taken`), named for the one lit landmark left unnamed;
    nothing unless there is exactly one of each."""
    left_ids = [i for i in lit_ids if i not in named]
    free = [k for k in range(len(spots)) if k not in taken]
    if len(left_ids) != 1 or len(free) != 1:
        return {}
    return {left_ids[0]: spots[free[0]]}


def _named_by_hypothesis(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    lit_ids: list[int],
    spots: FloatArray,
    named: dict[int, FloatArray],
    taken: set[int],
    cfg: IdentifyConfig,
) -> dict[int, FloatArray]:
    """Two more names for leftover spots: the only naming whose four-landmark camera pose
    fits within `max_pose_rms_px` (nothing when none does or more than one does)."""
    left_ids = [i for i in lit_ids if i not in named]
    free = [k for k in range(len(spots)) if k not in taken]
    spot_pairs = list(permutations(free, 2))
    id_pairs = [p for p in permutations(left_ids, 2) if p[0] < p[1]]
    if not spot_pairs or not id_pairs or len(spot_pairs) * len(id_pairs) > cfg.max_hypotheses:
        return {}
    ids = [*named, 0, 0]
    px = np.array([*named.values(), spots[0], spots[0]])
    fits: list[tuple[float, dict[int, FloatArray]]] = []
    for a, b in spot_pairs:
        for i, j in id_pairs:
            ids[2:], px[2], px[3] = [i, j], spots[a], spots[b]
            pose = camera_pose_from_landmarks(
                camera, px, landmark_map.positions[[landmark_map.index_of(k) for k in ids]]
            )
            if pose is not None and pose.residual_rms_px <= cfg.max_pose_rms_px:
                fits.append((pose.residual_rms_px, {i: spots[a], j: spots[b]}))
    return fits[0][1] if len(fits) == 1 else {}


def _named_by_prediction(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    lit_ids: list[int],
    spots: FloatArray,
    T_camera_world: FloatArray,
    limit_px: float,
) -> dict[int, FloatArray]:
    rows = [landmark_map.index_of(i) for i in lit_ids]
    pred, valid = pixels_from_points_camera(
        camera, transform_points(T_camera_world, landmark_map.positions[rows])
    )
    ids = [i for i, v in zip(lit_ids, valid, strict=True) if v]
    return {ids[c]: spots[s] for s, c in _match(spots, pred[valid], limit_px)}
