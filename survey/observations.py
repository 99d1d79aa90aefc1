"""Which spot is which landmark during a survey drive: spot tracks named by blinks.

A survey starts with most landmark positions unknown or rough, so the localizer's way of
naming spots (predict each landmark's pixel from the pose) does not apply. Instead:

1. **Tracks.** Spots are followed from frame to frame in the image: each track's pixel is
   carried to the next frame through the wheels' motion (the ray meets the ceiling, the
   point moves with the inverse of the body's motion, and is projected again), then tracks
   and spots are paired by least total distance within a gate (`linear_sum_assignment`).
   A track that finds no spot coasts on its prediction for a few frames, so a landmark that
   blinks dark keeps its track.
2. **Names.** A track that vanishes exactly while one landmark is dark and is back when it is
   lit again votes for that landmark (`survey.blinks`); a track seen in a frame where only
   one landmark was lit (the start-up sweep, Sec. III-A) votes for it. A track seen while a
   landmark was surely dark (a frame exposed after the switch was stamped and before the next
   switch can have happened) cannot be that landmark: each such dark window counts against
   the name. A track takes the name most of its votes give, if they agree clearly with the
   evidence against counted in.
3. **One spot per name at a time.** Two tracks seen in one frame cannot both be one
   landmark: the one with fewer votes loses the name (a spot that vanished by chance during
   another landmark's blink), both on a tie. Only if both are sure (`sure_votes`: a chance
   vanishing rarely repeats) do they keep it, reported as a conflict: two landmarks answering
   to one radio address.

Everything here is pure: frames arrive as detected spot pixels with their time and the LED
state in force.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.events import LedsChanged
from localizer.geometry import transform_points
from localizer.types import BoolArray, FloatArray, IntArray
from survey.ceiling import ceiling_points_body


@dataclass(frozen=True)
class TrackingConfig:
    """Tuning of the spot tracks and their naming.

    Attributes:
        gate_px: a spot pairs with a track's prediction within this distance, pixels.
        max_coast_frames: a track with no spot for this many frames in which no landmark
            was dark ends (a spot gone while every LED is lit is gone).
        max_coast_s: ... or for this long, blinks or not (a dark window lasts as long as the
            radio and the camera take: a fraction of a second, more on a busy server).
        edge_margin_px: a coasting track whose prediction comes this close to the image edge
            (or leaves the field of view) cannot vote: it may just have left the image.
        vote_margin_px: a track votes only if it vanished and came back this far inside the
            image (at the edge of a wide lens a dim spot fades in and out by itself).
        min_gap_frames: a track votes only if it stayed away this many frames (a spot
            missing from one frame is more often a flicker than a blink).
        max_dark_landmarks: a frame in which more landmarks are dark than this cannot
            name a vanished track (the vanishing would be ambiguous).
        min_agreement: share of a track's votes its name needs.
        led_time_tolerance_s: how late an LED state may be stamped after the LED switched
            (a live recording stamps the radio's confirmation), seconds.
        exposure_s: how long before its stamp a frame's exposure may begin, seconds (a frame
            is evidence of a dark LED only if it began after the switch was stamped).
        sure_votes: two tracks seen at once with one name both keep it only if each has this
            many votes (two landmarks answering to one address, reported as a conflict);
            otherwise the one with fewer votes loses it, both on a tie.
    """

    gate_px: float = 8.0
    max_coast_frames: int = 8
    max_coast_s: float = 1.0
    edge_margin_px: float = 6.0
    vote_margin_px: float = 25.0
    min_gap_frames: int = 2
    max_dark_landmarks: int = 1
    min_agreement: float = 0.75
    led_time_tolerance_s: float = 0.06
    exposure_s: float = 0.01
    sure_votes: int = 3


@dataclass(frozen=True, eq=False)
class LabelledObservations:
    """Spots named by landmark, over the frames of a drive.

    Every spot of every track is kept, named or not: the estimator confirms names by geometry
    and names more tracks by where they sit (`survey.bundle`).

    Attributes:
        frame: index into the frame list, shape (M,).
        landmark_id: the name the blinks gave the spot's track, -1 for none, shape (M,).
        name_votes: blink votes for that name, shape (M,) (0 for unnamed tracks).
        pixels: measured spot centres (col, row), shape (M, 2).
        track: the spot track each observation belongs to, shape (M,).
        conflicts: landmark id -> how many of its tracks disagreed with the others in one
            frame (two spots named alike at once: a swapped or duplicated radio address).
        votes: landmark id -> blink votes its tracks received.
        tracks: number of tracks followed; named: how many got a name.
    """

    frame: IntArray
    landmark_id: IntArray
    pixels: FloatArray
    track: IntArray
    name_votes: IntArray
    conflicts: dict[int, int] = field(default_factory=dict)
    votes: dict[int, int] = field(default_factory=dict)
    tracks: int = 0
    named: int = 0

    def __len__(self) -> int:
        return len(self.frame)

    def seen_ids(self) -> set[int]:
        """Landmarks named by at least one blink."""
        return {int(i) for i in np.unique(self.landmark_id) if i >= 0}


@dataclass
class _Track:
    pixel: FloatArray
    born: int
    last_seen: int
    frames: list[int] = field(default_factory=list)
    pixels: list[tuple[float, float]] = field(default_factory=list)
    coast: list[int] = field(default_factory=list)  # frames coasted in the current gap
    coast_ok: bool = True  # the current gap's predictions stayed well inside the image
    coast_unexplained: int = 0  # frames of the current gap with every LED lit
    votes: Counter[int] = field(default_factory=Counter)
    seen_in: set[int] = field(default_factory=set)  # settled LED states it was seen in


def lit_index_at_frames(frame_t_ns: Sequence[int], leds: Sequence[LedsChanged]) -> list[int]:
    """Index into `leds` of the state in force at each frame time (-1 before the first)."""
    times = [c.t_ns for c in leds]
    return [int(np.searchsorted(times, t, side="right")) - 1 for t in frame_t_ns]


def lit_state_at_frames(
    frame_t_ns: Sequence[int], leds: Sequence[LedsChanged]
) -> list[LedsChanged | None]:
    """The LED state in force at each frame time (None before the first state)."""
    return [leds[i] if i >= 0 else None for i in lit_index_at_frames(frame_t_ns, leds)]


def settled_states(
    frame_t_ns: Sequence[int], leds: Sequence[LedsChanged], before_ns: int, after_ns: int
) -> list[int]:
    """Per frame, the index into `leds` of a state with some landmark dark that was stamped
    `before_ns` or more before the frame and held until `after_ns` after it, else -1.

    A state is stamped when the switch was confirmed, up to `after_ns` after the LEDs
    switched: such a frame surely shows that state (the LEDs had switched before the stamp,
    and switch again no earlier than `after_ns` before the next stamp)."""
    now = lit_index_at_frames(frame_t_ns, leds)
    early = lit_index_at_frames([int(t) - before_ns for t in frame_t_ns], leds)
    late = lit_index_at_frames([int(t) + after_ns for t in frame_t_ns], leds)
    return [
        i if i >= 0 and i == e == la and not leds[i].all_lit else -1
        for i, e, la in zip(now, early, late, strict=True)
    ]


def predict_pixels_after_motion(
    camera: CameraModel, pixels: FloatArray, delta: FloatArray, ceiling_z_m: float
) -> tuple[FloatArray, BoolArray]:
    """Where ceiling spots (N, 2) appear after the body moved by `delta` (dx, dy, dtheta) in
    its own frame; their rays are taken to meet the ceiling at `ceiling_z_m` above the floor.
    """
    if len(pixels) == 0:
        return np.zeros((0, 2)), np.zeros(0, dtype=bool)
    p, ok = ceiling_points_body(camera, pixels, ceiling_z_m)
    c, si = math.cos(delta[2]), math.sin(delta[2])
    x, y = p[:, 0] - delta[0], p[:, 1] - delta[1]
    p_new = np.stack([c * x + si * y, -si * x + c * y, p[:, 2]], axis=1)
    px, valid = pixels_from_points_camera(camera, transform_points(camera.T_camera_body, p_new))
    return px, valid & ok


def _dark_of(state: LedsChanged | None, ids: frozenset[int]) -> frozenset[int] | None:
    """Landmarks dark in a state (None: unknown, before any state)."""
    if state is None:
        return None
    return frozenset() if state.all_lit else ids - state.lit


def label_spot_tracks(
    camera: CameraModel,
    landmark_ids: Sequence[int],
    frame_t_ns: Sequence[int],
    frame_spots: Sequence[FloatArray],
    frame_motion: FloatArray,
    leds: Sequence[LedsChanged],
    *,
    ceiling_z_m: float,
    config: TrackingConfig | None = None,
) -> LabelledObservations:
    """Follow the spots of a drive and name the tracks by the LED blinks.

    Args:
        camera: the surveying camera.
        landmark_ids: every landmark of the site (the LED states refer to them).
        frame_t_ns: frame times, shape (F,).
        frame_spots: each frame's spot pixels, shape (N_f, 2).
        frame_motion: body motion from each frame to the next in the earlier frame's own
            frame (dx, dy, dtheta), shape (F - 1, 3), e.g. from the wheels.
        leds: LED states in time order.
        ceiling_z_m: typical landmark height, metres (for carrying spots between frames).
    """
    cfg = config or TrackingConfig()
    ids = frozenset(int(i) for i in landmark_ids)
    states = lit_state_at_frames(frame_t_ns, leds)
    dark = [_dark_of(s, ids) for s in states]
    # a recording made live stamps each LED change when the radio confirmed it, up to a
    # radio round trip after the LED switched: judge a frame also by the state a moment later
    tol_ns = round(cfg.led_time_tolerance_s * 1e9)
    later = lit_state_at_frames([int(t) + tol_ns for t in frame_t_ns], leds)
    dark_late = [_dark_of(s, ids) for s in later]
    settled = settled_states(frame_t_ns, leds, round(cfg.exposure_s * 1e9), tol_ns)
    live: list[_Track] = []
    done: list[_Track] = []
    for f, spots in enumerate(frame_spots):
        spots = np.asarray(spots, dtype=np.float64).reshape(-1, 2)
        if f > 0 and live:
            pred, valid = predict_pixels_after_motion(
                camera, np.array([t.pixel for t in live]), frame_motion[f - 1], ceiling_z_m
            )
        else:
            pred, valid = np.zeros((len(live), 2)), np.ones(len(live), dtype=bool)
        pairs = _pair(pred, valid, spots, cfg.gate_px)
        matched_tracks = {ti for ti, _ in pairs}
        used_spots = {si for _, si in pairs}
        for ti, si in pairs:
            _resume(live[ti], f, spots[si], dark, dark_late, states, cfg, camera)
            if settled[f] >= 0:
                live[ti].seen_in.add(settled[f])
        still: list[_Track] = []
        for ti, t in enumerate(live):
            if ti in matched_tracks:
                still.append(t)
                continue
            inside = bool(valid[ti]) and _inside(camera, pred[ti], cfg.edge_margin_px)
            if not _either(dark[f], dark_late[f]):
                t.coast_unexplained += 1
            if (
                not inside
                or t.coast_unexplained > cfg.max_coast_frames
                or (int(frame_t_ns[f]) - int(frame_t_ns[t.last_seen])) * 1e-9 > cfg.max_coast_s
            ):
                done.append(t)
                continue
            t.pixel = pred[ti]
            if not t.coast:  # where it vanished: near the edge a spot can fade by itself
                t.coast_ok = _inside(camera, t.pixel, cfg.vote_margin_px)
            t.coast.append(f)
            t.coast_ok = t.coast_ok and _inside(camera, pred[ti], cfg.vote_margin_px)
            still.append(t)
        for si in range(len(spots)):
            if si not in used_spots:
                t = _Track(spots[si].copy(), f, f, [f], [(spots[si, 0], spots[si, 1])])
                _vote_single_lit(t, f, states)
                if settled[f] >= 0:
                    t.seen_in.add(settled[f])
                still.append(t)
        live = still
    done.extend(live)
    return _observations(done, cfg, leds)


def _pair(
    pred: FloatArray, valid: BoolArray, spots: FloatArray, gate_px: float
) -> list[tuple[int, int]]:
    if len(pred) == 0 or len(spots) == 0:
        return []
    cost = np.linalg.norm(pred[:, None, :] - spots[None, :, :], axis=2)
    cost[~valid] = 1e6
    rows, cols = linear_sum_assignment(np.where(cost <= gate_px, cost, 1e6))
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if cost[r, c] <= gate_px]


def _inside(camera: CameraModel, px: FloatArray, margin: float) -> bool:
    return bool(
        margin <= px[0] <= camera.width - 1 - margin
        and margin <= px[1] <= camera.height - 1 - margin
    )


def _resume(
    t: _Track,
    f: int,
    spot: FloatArray,
    dark: list[frozenset[int] | None],
    dark_late: list[frozenset[int] | None],
    states: list[LedsChanged | None],
    cfg: TrackingConfig,
    camera: CameraModel,
) -> None:
    """A track finds its spot again at frame f: a gap that matched one dark landmark votes."""
    if t.coast:
        gap = t.coast
        before, after = gap[0] - 1, f
        gap_dark = [_either(dark[g], dark_late[g]) for g in gap]
        known = [d for d in gap_dark if d is not None]
        clear = (
            t.coast_ok
            and len(gap) >= cfg.min_gap_frames
            and _inside(camera, spot, cfg.vote_margin_px)
        )
        if (
            clear
            and len(known) == len(gap)
            and all(len(d) <= cfg.max_dark_landmarks for d in known)
        ):
            union = frozenset().union(*known)
            dark_frames = sum(1 for d in known if d)
            seen_before = dark[before]
            if len(union) == 1 and 2 * dark_frames >= len(gap) and seen_before is not None:
                (lid,) = union
                after_lit = any(
                    d is not None and lid not in d for d in (dark[after], dark_late[after])
                )
                if lid not in seen_before and after_lit:
                    t.votes[lid] += 1
        t.coast = []
        t.coast_unexplained = 0
    t.pixel = spot.copy()
    t.last_seen = f
    t.frames.append(f)
    t.pixels.append((float(spot[0]), float(spot[1])))
    _vote_single_lit(t, f, states)


def _either(a: frozenset[int] | None, b: frozenset[int] | None) -> frozenset[int] | None:
    """Landmarks dark in either of two states (None when neither is known)."""
    if a is None or b is None:
        return a if b is None else b
    return a | b


def _vote_single_lit(t: _Track, f: int, states: list[LedsChanged | None]) -> None:
    s = states[f]
    if s is not None and not s.all_lit and len(s.lit) == 1:
        (lid,) = s.lit
        t.votes[lid] += 1


def track_name(
    votes: Counter[int], against: Callable[[int], int], min_agreement: float
) -> tuple[int, int]:
    """A track's name and the votes for it, (-1, 0) for none: the most voted landmark, if its
    votes are `min_agreement` of all the track's votes and the dark windows it was seen in
    (`against(lid)`: each says it is not that landmark)."""
    if not votes:
        return -1, 0
    (best, top), total = votes.most_common(1)[0], sum(votes.values())
    if top >= min_agreement * (total + against(best)):
        return best, top
    return -1, 0


def _dark_windows_seen(t: _Track, leds: Sequence[LedsChanged]) -> Callable[[int], int]:
    """How many settled states with landmark `lid` dark the track was seen in."""

    def against(lid: int) -> int:
        return sum(1 for i in t.seen_in if lid not in leds[i].lit)

    return against


def _one_spot_per_name(names: list[tuple[int, int]], tracks: list[_Track], sure: int) -> None:
    """One spot per landmark at a time: of tracks seen in one frame with one name, unname
    (in place) each with fewer votes than another, or as many, unless both have `sure`."""
    by_name: dict[int, list[int]] = {}
    for k, (lid, _) in enumerate(names):
        if lid >= 0:
            by_name.setdefault(lid, []).append(k)
    for ks in by_name.values():
        if len(ks) < 2:
            continue
        frames = {k: set(tracks[k].frames) for k in ks}
        votes = {k: names[k][1] for k in ks}
        for k in ks:
            if any(
                j != k
                and votes[j] >= votes[k]
                and min(votes[j], votes[k]) < sure
                and not frames[k].isdisjoint(frames[j])
                for j in ks
            ):
                names[k] = (-1, 0)


def _observations(
    tracks: list[_Track], cfg: TrackingConfig, leds: Sequence[LedsChanged]
) -> LabelledObservations:
    frames: list[int] = []
    lids: list[int] = []
    n_votes: list[int] = []
    pixels: list[tuple[float, float]] = []
    track_ix: list[int] = []
    votes: Counter[int] = Counter()
    seen_at: dict[tuple[int, int], int] = {}
    conflicts: Counter[int] = Counter()
    names = [track_name(t.votes, _dark_windows_seen(t, leds), cfg.min_agreement) for t in tracks]
    _one_spot_per_name(names, tracks, cfg.sure_votes)
    for k, (t, (lid, n)) in enumerate(zip(tracks, names, strict=True)):
        if lid >= 0:
            votes[lid] += n
        for f, px in zip(t.frames, t.pixels, strict=True):
            if lid >= 0:
                other = seen_at.setdefault((f, lid), k)
                if other != k:
                    conflicts[lid] += 1
            frames.append(f)
            lids.append(lid)
            n_votes.append(n)
            pixels.append(px)
            track_ix.append(k)
    order = np.argsort(np.asarray(frames, dtype=np.int64), kind="stable")
    return LabelledObservations(
        np.asarray(frames, dtype=np.int64)[order],
        np.asarray(lids, dtype=np.int64)[order],
        np.asarray(pixels, dtype=np.float64).reshape(-1, 2)[order],
        np.asarray(track_ix, dtype=np.int64)[order],
        np.asarray(n_votes, dtype=np.int64)[order],
        dict(conflicts),
        dict(votes),
        len(tracks),
        sum(1 for lid, _ in names if lid >= 0),
    )
