"""What a pose is worth: its honest covariance, the 95 % radius and a 0-1 quality.

Pure functions (numpy in, numpy out). The localizer's filter carries the covariance it
tracks with; what it publishes is that covariance made honest (`published_covariance`):
measured on every benchmark recording with truth (`bench/consistency.py`), the filter's
covariance alone held too few errors inside its ellipse, because

- the published pose is the filter's output, which follows a correction with a time
  constant (`FilterConfig.output_time_constant_s`): the output's offset from the estimate
  is a known displacement the covariance does not hold;
- a fix's systematic error (calibration, survey) and the odometry's (bias, slip) are only
  partly in the noise model; a per-mode scale and a floor cover what is left.

`deviation_radius_m` is the radius of the circle around the pose that holds the true
position with probability 0.95 under that covariance (the Hoyt distribution of a 2-D
Gaussian error, computed by quadrature), and `quality_from_deviation` maps it to 0-1 on a
logarithmic scale (docs/quality.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np
import numpy.typing as npt
from scipy.special import erf

from localizer.camera import CameraModel, predict_pixels
from localizer.geometry import T_world_body_from_pose

FloatArray = npt.NDArray[np.float64]

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(32)  # quadrature on [-1, 1] (constants)
_RHO = np.linspace(0.0, 1.0, 21)
_K95 = np.array([
    1.959964, 1.960016, 1.962035, 1.965510, 1.970217, 1.976357, 1.984076, 1.993555, 2.005051,
    2.018942, 2.035793, 2.056327, 2.081254, 2.111068, 2.145942, 2.185768, 2.230257, 2.279048,
    2.331774, 2.388098, 2.447747,
])  # fmt: skip
"""r / sd_major of the 95 % circle at sd_minor / sd_major = `_RHO` (roots of
`circle_probability` = 0.95; tests/localizer/test_pose_quality.py checks them)."""
_STEPS = len(_RHO) - 1
_K95_LIST: list[float] = _K95.tolist()  # read per pose: plain floats


def _per_mode(landmark: float, dead_reckoning: float, lost: float) -> dict[str, float]:
    """A per-mode value; identifying (a prior without a fix yet) as dead reckoning."""
    return {
        "landmark": landmark,
        "dead_reckoning": dead_reckoning,
        "identifying": dead_reckoning,
        "lost": lost,
    }


MODES = tuple(_per_mode(0.0, 0.0, 0.0))
"""The localizer's modes (`localizer.events.Mode`, which imports this module's reasons)."""


@dataclass(frozen=True)
class QualityConfig:
    """The 0-1 quality's scale, and how the filter's covariance is made honest per mode
    (SI units; docs/quality.md).

    Attributes:
        good_m: a 95 % radius at or under this is quality 1, metres.
        useless_m: at or over this, quality 0, metres; logarithmic in between.
        position_scale: per mode, the factor on the filter's position standard deviations.
        heading_scale: per mode, the factor on its heading standard deviation.
        position_floor_m: per mode, a standard deviation added in quadrature to each
            position axis (what no noise model holds: the survey's and the calibration's
            error on a fix), metres.
        heading_floor_rad: per mode, the same for the heading, radians.
        output_offset: add the output's offset from the estimate (the smoothing) as a
            known error: P + o o^T.
    """

    good_m: float = 0.03
    useless_m: float = 1.0
    position_scale: dict[str, float] = field(default_factory=lambda: _per_mode(2.0, 2.0, 2.0))
    heading_scale: dict[str, float] = field(default_factory=lambda: _per_mode(1.5, 1.0, 1.0))
    position_floor_m: dict[str, float] = field(default_factory=lambda: _per_mode(0.01, 0.02, 1.0))
    heading_floor_rad: dict[str, float] = field(
        default_factory=lambda: _per_mode(0.001, 0.001, 0.0)
    )
    output_offset: bool = True

    def __post_init__(self) -> None:
        if not (0 < self.good_m < self.useless_m and math.isfinite(self.useless_m)):
            raise ValueError(
                f"QualityConfig: need 0 < good_m < useless_m, got {self.good_m!r}, "
                f"{self.useless_m!r}"
            )
        for name in ("position_scale", "heading_scale", "position_floor_m", "heading_floor_rad"):
            for mode, v in getattr(self, name).items():
                if mode not in MODES:
                    raise ValueError(
                        f"QualityConfig: {name} has an unknown mode {mode!r} "
                        f"(the modes: {', '.join(MODES)})"
                    )
                low_ok = v > 0 if name.endswith("scale") else v >= 0
                if not (math.isfinite(v) and low_ok):
                    raise ValueError(f"QualityConfig: {name}[{mode!r}] out of range: {v!r}")


def published_covariance(
    covariance: FloatArray,
    mode: str,
    output_offset: tuple[float, float, float],
    config: QualityConfig,
) -> FloatArray:
    """The covariance published with a pose, from the filter's.

    P_pub = S P S + diag(f_xy^2, f_xy^2, f_theta^2) + o o^T, with S = diag(s_xy, s_xy,
    s_theta) the mode's scales, f its floors and o the output's offset from the estimate
    (x, y, theta); shape (3, 3) in, (3, 3) out.
    """
    P = np.asarray(covariance, dtype=np.float64)
    if P.shape != (3, 3):
        raise ValueError(f"published_covariance: covariance must be (3, 3), got {P.shape}")
    s_xy = config.position_scale.get(mode, 1.0)
    s_th = config.heading_scale.get(mode, 1.0)
    f_xy = config.position_floor_m.get(mode, 0.0)
    f_th = config.heading_floor_rad.get(mode, 0.0)
    S = (s_xy, s_xy, s_th)
    F = (f_xy * f_xy, f_xy * f_xy, f_th * f_th)
    o = output_offset if config.output_offset else (0.0, 0.0, 0.0)
    rows = P.tolist()  # nine floats: plain arithmetic is cheaper than numpy at this size
    out = [
        [
            0.5 * (rows[i][j] + rows[j][i]) * S[i] * S[j] + o[i] * o[j] + (F[i] if i == j else 0.0)
            for j in range(3)
        ]
        for i in range(3)
    ]
    return np.array(out, dtype=np.float64)


def circle_probability(r: float, sd_major: float, sd_minor: float) -> float:
    """P(|e| <= r) for e ~ N(0, diag(sd_major^2, sd_minor^2)): the integral over the major
    axis of the minor axis's probability inside the chord, by Gauss-Legendre quadrature."""
    x = r * _NODES
    half = np.sqrt(np.maximum(r * r - x * x, 0.0))
    inner = erf(half / (math.sqrt(2.0) * sd_minor))
    density = np.exp(-0.5 * (x / sd_major) ** 2) / (math.sqrt(2.0 * math.pi) * sd_major)
    return float(r * np.sum(_WEIGHTS * density * inner))


def deviation_radius_m(covariance_xy: FloatArray) -> float:
    """The radius of the circle around the estimate that holds the true position with
    probability 0.95 (VDA 5050's `deviationRange`), metres.

    Args:
        covariance_xy: the position covariance, shape (2, 2) (or the pose's (3, 3)).

    Returns:
        r with P(|e| <= r) = 0.95 for e ~ N(0, P_xy): k(rho) sd_major, rho = sd_minor /
        sd_major, from 1.960 (a flat ellipse: the 1-D quantile) to 2.448 (a circle,
        sqrt(-2 ln 0.05)); k is tabulated from `circle_probability` (linear interpolation,
        within 0.03 % of the root).
    """
    P = np.asarray(covariance_xy, dtype=np.float64)
    (a, b1), (b2, c) = (row[:2] for row in P[:2].tolist())
    if not all(math.isfinite(v) for v in (a, b1, b2, c)):
        raise ValueError("deviation_radius_m: the covariance has a non-finite entry")
    mid, half = 0.5 * (a + c), math.hypot(0.5 * (a - c), 0.5 * (b1 + b2))
    sd_major = math.sqrt(max(mid + half, 0.0))
    if sd_major == 0.0:
        return 0.0
    rho = min(math.sqrt(max(mid - half, 0.0)) / sd_major, 1.0)
    k = min(int(rho * _STEPS), _STEPS - 1)  # _RHO is evenly spaced: interpolate in cell k
    w = rho * _STEPS - k
    return ((1.0 - w) * _K95_LIST[k] + w * _K95_LIST[k + 1]) * sd_major


def heading_deviation_rad(covariance: FloatArray) -> float:
    """The heading's 95 % bound (1.96 sigma), radians, from the pose covariance (3, 3)."""
    return 1.959963984540054 * math.sqrt(max(float(np.asarray(covariance)[2, 2]), 0.0))


def quality_from_deviation(deviation_m: float | None, config: QualityConfig) -> float:
    """The 0-1 quality of a pose whose 95 % radius is `deviation_m` (None: no pose, 0).

    q = 1 - log(d / good_m) / log(useless_m / good_m), clipped to [0, 1]: with the
    defaults 3 cm -> 1, 5 cm -> 0.85, 10 cm -> 0.66, 25 cm -> 0.40, 1 m -> 0.
    """
    if deviation_m is None or not math.isfinite(deviation_m):
        return 0.0
    if deviation_m <= config.good_m:
        return 1.0
    q = 1.0 - math.log(deviation_m / config.good_m) / math.log(config.useless_m / config.good_m)
    return min(max(q, 0.0), 1.0)


ReasonCode = Literal[
    "identifying",
    "waiting_for_radio",
    "lost",
    "kidnapped_suspected",
    "camera_stale",
    "frames_dropped",
    "odometry_stale",
    "odometry_slipping",
    "spots_rejected_gate",
    "spots_rejected_glint",
    "landmarks_dark",
    "landmark_dead",
    "landmarks_not_seen",
    "one_landmark_only",
    "no_landmark_in_view",
]
"""Why a pose is not a landmark fix (docs/quality.md has a row per code)."""
REASON_CODES: tuple[ReasonCode, ...] = get_args(ReasonCode)

REASON_TEXT: dict[ReasonCode, str] = {
    "identifying": "identifying the landmarks in view by switching their LEDs",
    "waiting_for_radio": "waiting for the radio to confirm an LED switch",
    "lost": "lost: the position uncertainty grew past the limit; identifying again",
    "kidnapped_suspected": "lost: the landmarks seen disagree with the pose "
    "(moved without the wheels knowing?); identifying again",
    "camera_stale": "no camera frame for {gap_s:.1f} s",
    "frames_dropped": "a camera frame could not be read",
    "odometry_stale": "no wheel odometry for {odometry_age_s:.1f} s",
    "odometry_slipping": "fixes from the landmarks have disagreed with the wheel odometry "
    "for {rejections} frames (wheel slip?)",
    "spots_rejected_gate": "a fix from the landmarks was too far from the odometry's pose "
    "and was not taken",
    "spots_rejected_glint": "spots where landmarks should be did not fit them "
    "(a reflection or stray light?)",
    "landmarks_dark": "the {dark} landmark(s) in view are switched off by the LED schedule",
    "landmark_dead": "landmark(s) {dead_ids} in view should be lit but are never seen "
    "(a dead LED or battery?)",
    "landmarks_not_seen": "{lit} lit landmark(s) in view were not detected",
    "one_landmark_only": "only one landmark in view; a fix needs two",
    "no_landmark_in_view": "no mapped landmark in view (dead reckoning on the wheels)",
}


@dataclass(frozen=True)
class FrameFacts:
    """What the localizer knew of one frame that explains why it had no fix.

    Attributes:
        mode: the localizer's mode after the frame.
        fused: a fix from the landmarks was fused (or re-seeded the filter) this frame.
        lost_by_disagreement: in `lost` because the observations kept disagreeing with the
            pose (not because the uncertainty grew).
        in_view: mapped landmarks the pose places inside the image, whatever their LED.
        lit_in_view: of those, surely lit (not being switched).
        switching_in_view: of those, being switched (the command not confirmed).
        dark_ids: of those, dark by the LED state (the schedule, a probe).
        dead_ids: of the lit ones, those tracking has never seen while predicted in view.
        unexplained: spots were seen near 2+ predicted landmarks but no fix explained them.
        rejected_fix: a fix consistent in itself failed the innovation gate.
        rejections: frames in a row with no fix explaining the spots.
        gap_s: time since the frame before, seconds (0: the first).
        typical_gap_s: the usual frame interval, seconds (0: not known yet).
        skipped: the frame could not be read (`Localizer.skip_frame`).
        odometry_age_s: time since the last odometry sample, seconds (inf: none yet).
        odometry_stale_s: beyond this the odometry is stale, seconds.
        awaiting_leds: an LED request was made and not yet confirmed.
    """

    mode: str
    fused: bool = False
    lost_by_disagreement: bool = False
    in_view: int = 0
    lit_in_view: int = 0
    switching_in_view: int = 0
    dark_ids: tuple[int, ...] = ()
    dead_ids: tuple[int, ...] = ()
    unexplained: bool = False
    rejected_fix: bool = False
    rejections: int = 0
    gap_s: float = 0.0
    typical_gap_s: float = 0.0
    skipped: bool = False
    odometry_age_s: float = math.inf
    odometry_stale_s: float = 0.2
    awaiting_leds: bool = False


def camera_stale(gap_s: float, typical_gap_s: float) -> bool:
    """A frame after a gap of more than three usual intervals (and over 0.2 s)."""
    return typical_gap_s > 0 and gap_s > max(3.0 * typical_gap_s, 0.2)


def is_landmark_fix(mode: str, fused: bool) -> bool:
    """A frame that fused a landmark fix in landmark mode: it has no reason to give."""
    return fused and mode == "landmark"


def reason_for(facts: FrameFacts) -> ReasonCode | None:
    """The reason a frame had no landmark fix (None: it had one), the most telling first:
    the mode, then a sensor's fault, then spots that did not fit, then what the ceiling
    showed."""
    f = facts
    if is_landmark_fix(f.mode, f.fused):
        return None
    if f.mode == "identifying":
        return "waiting_for_radio" if f.awaiting_leds or f.switching_in_view else "identifying"
    if f.mode == "lost":
        return "kidnapped_suspected" if f.lost_by_disagreement else "lost"
    if f.skipped:
        return "frames_dropped"
    if camera_stale(f.gap_s, f.typical_gap_s):
        return "camera_stale"
    if f.odometry_age_s > f.odometry_stale_s:
        return "odometry_stale"
    if f.rejected_fix:
        return "odometry_slipping" if f.rejections >= 3 else "spots_rejected_gate"
    if f.dead_ids and f.lit_in_view - len(f.dead_ids) < 2:
        return "landmark_dead"
    if f.unexplained:
        return "spots_rejected_glint"
    if f.switching_in_view and f.lit_in_view < 2:
        return "waiting_for_radio"
    if f.dark_ids and f.lit_in_view < 2:
        return "landmarks_dark"
    if f.lit_in_view >= 2:
        return "landmarks_not_seen"
    if f.in_view == 1 or f.lit_in_view == 1:
        return "one_landmark_only"
    return "no_landmark_in_view"


def reason_text(code: ReasonCode, facts: FrameFacts) -> str:
    """The sentence for people that goes with a reason code."""
    f = facts
    return REASON_TEXT[code].format(
        gap_s=f.gap_s,
        odometry_age_s=f.odometry_age_s,
        rejections=f.rejections,
        dark=len(f.dark_ids),
        dead_ids=", ".join(str(i) for i in f.dead_ids),
        lit=f.lit_in_view,
    )


def landmarks_in_view(
    camera: CameraModel,
    pose: tuple[float, float, float],
    positions: FloatArray,
    reach_m: float,
) -> npt.NDArray[np.bool_]:
    """Which landmarks a level body at `pose` (x, y, theta) sees inside the image: within
    `reach_m` horizontally, then projected (eq. 3); `positions` (N, 3), mask (N,)."""
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    near = np.hypot(P[:, 0] - pose[0], P[:, 1] - pose[1]) <= reach_m
    out = np.zeros(len(P), dtype=bool)
    if not near.any():
        return out
    px, valid = predict_pixels(camera, T_world_body_from_pose(*pose), P[near])
    inside = (
        valid
        & (px[:, 0] >= 0)
        & (px[:, 0] < camera.width)
        & (px[:, 1] >= 0)
        & (px[:, 1] < camera.height)
    )
    out[np.flatnonzero(near)[inside]] = True
    return out
