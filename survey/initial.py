"""A starting point for the survey's bundle adjustment: keyframe poses by dead reckoning,
re-anchored by a pose fix (`localizer.pose.solve_pose`) wherever two or more landmarks with a
position (the anchors, a rough one, or one placed already) are in view, and each new
landmark placed where its ray meets the ceiling.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel
from localizer.pose import solve_pose
from localizer.types import FloatArray, IntArray
from survey.ceiling import ceiling_points_world
from survey.odometry_chain import compose, dead_reckoning


def invert_deltas(deltas: FloatArray) -> FloatArray:
    """The inverse motions (K, 3): from the end of each interval back to its start."""
    c, s = np.cos(deltas[:, 2]), np.sin(deltas[:, 2])
    out = np.empty_like(deltas)
    out[:, 0] = -(c * deltas[:, 0] + s * deltas[:, 1])
    out[:, 1] = -(-s * deltas[:, 0] + c * deltas[:, 1])
    out[:, 2] = -deltas[:, 2]
    return out


def initial_guess(
    camera: CameraModel,
    deltas: FloatArray,
    obs_key: IntArray,
    obs_id: IntArray,
    obs_px: FloatArray,
    anchors: dict[int, FloatArray],
    rough: dict[int, FloatArray],
    ceiling_z_m: float,
    *,
    pixel_sigma_px: float,
    min_views: int = 3,
    max_spread_m: float = 0.08,
    max_jump_m: float = 0.3,
    max_turn_rad: float = math.radians(10.0),
    max_fix_rms_px: float = 4.0,
    prefix_poses: FloatArray | None = None,
    prefix_landmarks: dict[int, FloatArray] | None = None,
) -> tuple[FloatArray, dict[int, FloatArray]]:
    """Keyframe poses (K, 3) and a position for every observed landmark.

    Incremental, as structure from motion starts: the poses follow the wheels and are fixed
    (`solve_pose`) from landmarks whose position is trusted: the anchors, and each landmark
    once `min_views` of its rays agree within `max_spread_m` where they meet its ceiling
    height (rough positions only seed that height and landmarks never placed otherwise).
    A fix far from the wheels' prediction is not taken. Before the first fix the poses are
    the wheels' motion run backwards from it.

    Args:
        deltas: odometry motion between consecutive keyframes, shape (K - 1, 3).
        obs_key, obs_id, obs_px: observations (keyframe, landmark, pixel), sorted by keyframe.
        anchors, rough: positions given (held; a rough hint), metres.
        ceiling_z_m: height of landmarks with no position at all.
        max_fix_rms_px: a fix whose spots disagree by more than this is not taken.
        prefix_poses, prefix_landmarks: an estimate of the first keyframes and of landmarks
            already (a survey solved in growing windows); the rest continues from it.

    Raises:
        ValueError: when no keyframe sees two landmarks with a trusted or rough position.
    """
    K = len(deltas) + 1
    poses = np.full((K, 3), np.nan)
    good = {int(k): np.asarray(v, dtype=np.float64) for k, v in (prefix_landmarks or {}).items()}
    good.update({int(k): np.asarray(v, dtype=np.float64) for k, v in anchors.items()})
    points: dict[int, list[FloatArray]] = {}
    bounds = np.searchsorted(obs_key, np.arange(K + 1))
    pose: FloatArray | None = None
    n_prefix = 0 if prefix_poses is None else min(len(prefix_poses), K)
    for k in range(K):
        predicted = None if pose is None else compose(pose[None, :], deltas[k - 1][None, :])[0]
        sl = slice(bounds[k], bounds[k + 1])
        ids, px = obs_id[sl], obs_px[sl]
        if k < n_prefix and prefix_poses is not None:
            poses[k] = pose = prefix_poses[k]
            continue
        pose = _fix(
            camera,
            ids,
            px,
            good,
            predicted,
            pixel_sigma_px,
            max_jump_m,
            max_turn_rad,
            max_fix_rms_px,
        )
        if pose is None:
            continue
        poses[k] = pose
        new = [i for i, lid in enumerate(ids.tolist()) if lid not in good]
        if not new:
            continue
        heights = [rough[lid][2] if lid in rough else ceiling_z_m for lid in ids[new].tolist()]
        qs, hit = ceiling_points_world(camera, np.tile(pose, (len(new), 1)), px[new], heights)
        for lid, q in zip(ids[new][hit].tolist(), qs[hit], strict=True):
            pts = points.setdefault(lid, [])
            pts.append(q)
            if len(pts) >= min_views:
                arr = np.array(pts[-4 * min_views :])
                if float(np.max(np.std(arr[:, :2], axis=0))) <= max_spread_m:
                    good[lid] = np.median(arr, axis=0)
    if not np.any(np.isfinite(poses[:, 0])):
        if not rough:
            raise ValueError(
                "survey: no frame sees two landmarks with a position; start the drive under "
                "the anchors, or give rough positions"
            )
        start = _start_from_rough_fixes(
            camera, deltas, obs_key, obs_id, obs_px, {**rough, **anchors}, pixel_sigma_px
        )
        return initial_guess(
            camera,
            deltas,
            obs_key,
            obs_id,
            obs_px,
            anchors,
            rough,
            ceiling_z_m,
            pixel_sigma_px=pixel_sigma_px,
            min_views=min_views,
            max_spread_m=max_spread_m,
            max_jump_m=max_jump_m,
            max_turn_rad=max_turn_rad,
            max_fix_rms_px=max_fix_rms_px,
            prefix_poses=dead_reckoning(
                (float(start[0]), float(start[1]), float(start[2])), deltas
            ),
        )
    first = int(np.flatnonzero(np.isfinite(poses[:, 0]))[0])
    back = invert_deltas(deltas)
    for k in range(first - 1, -1, -1):
        poses[k] = compose(poses[k + 1][None, :], back[k][None, :])[0]
    est = dict(good)
    for lid in {int(i) for i in obs_id.tolist()} - set(est):
        if lid in points:
            est[lid] = np.median(np.array(points[lid]), axis=0)
        elif lid in rough:
            est[lid] = rough[lid]
        else:
            rows = np.flatnonzero(obs_id == lid)
            qs, hit = ceiling_points_world(camera, poses[obs_key[rows]], obs_px[rows], ceiling_z_m)
            if hit.any():
                est[lid] = np.median(qs[hit], axis=0)
    return poses, est


def _fix(
    camera: CameraModel,
    ids: IntArray,
    px: FloatArray,
    good: dict[int, FloatArray],
    predicted: FloatArray | None,
    pixel_sigma_px: float,
    max_jump_m: float,
    max_turn_rad: float,
    max_fix_rms_px: float,
) -> FloatArray | None:
    """The keyframe's pose: a fix from the trusted landmarks in view if it agrees with the
    wheels' prediction (or there is none yet) and explains the spots (a misnamed spot does
    not), else the prediction."""
    have = [i for i, lid in enumerate(ids.tolist()) if lid in good]
    if len(have) < 2:
        return predicted
    fix = solve_pose(
        camera,
        px[have],
        np.array([good[int(ids[i])] for i in have]),
        initial=None
        if predicted is None
        else (float(predicted[0]), float(predicted[1]), float(predicted[2])),
        pixel_sigma_px=pixel_sigma_px,
    )
    if fix is None or fix.residual_rms_px > max_fix_rms_px:
        return predicted
    if predicted is None:
        return np.array([fix.x, fix.y, fix.theta])
    turn = math.remainder(fix.theta - predicted[2], math.tau)
    if (
        math.hypot(fix.x - predicted[0], fix.y - predicted[1]) > max_jump_m
        or abs(turn) > max_turn_rad
    ):
        return predicted
    return np.array([fix.x, fix.y, predicted[2] + turn])  # heading unwrapped along the drive


def _start_from_rough_fixes(
    camera: CameraModel,
    deltas: FloatArray,
    obs_key: IntArray,
    obs_id: IntArray,
    obs_px: FloatArray,
    positions: dict[int, FloatArray],
    pixel_sigma_px: float,
) -> FloatArray:
    """The start pose that best agrees with fixes from rough positions along the wheels' track.

    Each keyframe that sees two or more landmarks with any position gives a fix, off by about
    the rough positions' error; moved back to the start along the wheels' motion, they agree
    on the start pose up to that error, and their median averages it down.
    """
    dr = dead_reckoning((0.0, 0.0, 0.0), deltas)
    K = len(dr)
    bounds = np.searchsorted(obs_key, np.arange(K + 1))
    starts: list[FloatArray] = []
    for k in range(K):
        ids, px = obs_id[bounds[k] : bounds[k + 1]], obs_px[bounds[k] : bounds[k + 1]]
        have = [i for i, lid in enumerate(ids.tolist()) if lid in positions]
        if len(have) < 2:
            continue
        fix = solve_pose(
            camera,
            px[have],
            np.array([positions[int(ids[i])] for i in have]),
            pixel_sigma_px=pixel_sigma_px,
        )
        if fix is None:
            continue
        # the start: the fix moved back by the dead-reckoned motion to keyframe k
        fix_pose = np.array([[fix.x, fix.y, fix.theta]])
        starts.append(compose(fix_pose, invert_deltas(dr[k : k + 1]))[0])
        if len(starts) >= 200:
            break
    if not starts:
        raise ValueError("survey: no frame sees two landmarks with a position in map.json")
    a = np.array(starts)
    heading = math.atan2(float(np.median(np.sin(a[:, 2]))), float(np.median(np.cos(a[:, 2]))))
    return np.array([float(np.median(a[:, 0])), float(np.median(a[:, 1])), heading])
