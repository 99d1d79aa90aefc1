"""The buildings of the independent generator (`bench/foreign/generate.py`): chosen unlike
our own simulator's defaults on purpose (camera and odometry rates, resolutions, exposure
blur, spot shape, noise, ceiling heights, speeds), never tuned to pass."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
Layout = Callable[[np.random.Generator], FloatArray]


def grid(nx: int, ny: int, spacing: float, z: float, dz: float) -> Layout:
    def make(rng: np.random.Generator) -> FloatArray:
        xs, ys = np.meshgrid(np.arange(nx) * spacing, np.arange(ny) * spacing)
        p = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)])
        p[:, 2] += rng.uniform(-dz, dz, len(p))
        return p

    return make


def irregular(nx: int, ny: int, spacing: float, jitter: float, z: float, dz: float) -> Layout:
    def make(rng: np.random.Generator) -> FloatArray:
        p = grid(nx, ny, spacing, z, dz)(rng)
        p[:, :2] += rng.uniform(-jitter, jitter, (len(p), 2))
        return p

    return make


def corridor_pairs(z: float, dz: float) -> Layout:
    """Pairs 35-90 cm apart along a 14 m corridor, 1.6-2.2 m between pairs, one 5 m gap."""

    def make(rng: np.random.Generator) -> FloatArray:
        pts, x = [], 0.0
        while x < 14.0:
            gap = rng.uniform(0.35, 0.9)
            a = rng.uniform(0, math.pi)
            pts.append([x, 0.0, z])
            pts.append([x + gap * math.cos(a), gap * math.sin(a) - 0.2, z])
            x += rng.uniform(1.6, 2.2) + (5.0 if 6.0 < x < 8.0 else 0.0)
        p = np.array(pts)
        p[:, 2] += rng.uniform(-dz, dz, len(p))
        return p

    return make


def hall_with_skylights(spacing: float, z: float, dz: float) -> Layout:
    """A 9 x 7 m hall, landmarks on an irregular ~`spacing` grid, two skylights (no
    landmarks) and a few missing ones: the only features a lost robot can go by."""

    def make(rng: np.random.Generator) -> FloatArray:
        p = irregular(int(9 / spacing) + 1, int(7 / spacing) + 1, spacing, 0.1 * spacing, z, dz)(
            rng
        )
        sky = ((p[:, 0] > 2.0) & (p[:, 0] < 3.4) & (p[:, 1] > 1.0) & (p[:, 1] < 2.2)) | (
            (p[:, 0] > 5.6) & (p[:, 0] < 6.8) & (p[:, 1] > 4.0) & (p[:, 1] < 5.5)
        )
        keep = ~sky & (rng.random(len(p)) > 0.06)
        return p[keep]

    return make


def sparse(width: float, depth: float, min_gap: float, z: float, dz: float) -> Layout:
    """Landmarks scattered over a `width` x `depth` hall, none closer than `min_gap` to
    another (dart throwing): a high ceiling fitted out sparsely."""

    def make(rng: np.random.Generator) -> FloatArray:
        pts: list[list[float]] = []
        for _ in range(4000):
            q = [rng.uniform(0, width), rng.uniform(0, depth)]
            if all(math.hypot(q[0] - a, q[1] - b) >= min_gap for a, b, _ in pts):
                pts.append([q[0], q[1], z + rng.uniform(-dz, dz)])
        return np.array(pts)

    return make


def mezzanine(spacing: float, z_low: float, z_high: float, split_x: float) -> Layout:
    """An irregular ~`spacing` grid over a 10 x 6 m hall whose ceiling is `z_low` under a
    mezzanine (x < `split_x`) and `z_high` in the open part beyond it."""

    def make(rng: np.random.Generator) -> FloatArray:
        p = irregular(int(10 / spacing) + 1, int(6 / spacing) + 1, spacing, 0.15 * spacing, 0, 0)(
            rng
        )
        p[:, 2] = np.where(p[:, 0] < split_x, z_low, z_high) + rng.uniform(-0.03, 0.03, len(p))
        return p

    return make


def unequal_leds(n: int, seed: int) -> FloatArray:
    """LED outputs of an aged installation: log-normal spread (a factor ~1.6 either way),
    every 9th one at a fifth of the rest (a failing driver, near the detection threshold) and
    every 13th four times too bright (its image blooms)."""
    power = np.random.default_rng(seed).lognormal(0.0, 0.45, n)
    power[4::9] = 0.2
    power[6::13] = 4.0
    return power


def triangle(side: float, z: float) -> Layout:
    def make(rng: np.random.Generator) -> FloatArray:
        return np.array([[0.0, 0.0, z], [side, 0.0, z], [side / 2, side * math.sqrt(3) / 2, z]])

    return make


@dataclass(frozen=True)
class Case:
    """One building, robot and camera.

    segments: (duration s, v m/s, w rad/s) commands, repeated; the drive follows them with a
    first-order lag of `drive_lag_s`.
    """

    layout: Layout
    segments: tuple[tuple[float, float, float], ...]
    start: tuple[float, float, float]
    seconds: float = 40.0
    first_id: int = 300
    size: tuple[int, int] = (640, 480)
    f_px: float = 260.0
    aspect: float = 1.0
    c_off: tuple[float, float] = (3.1, -2.4)
    dist: tuple[float, ...] = (-0.012, 0.018, -0.009, 0.0016)
    fisheye: bool = True
    calib_error: float = 1.0  # 1: what Zhang's method leaves; 0: exact
    rate_hz: float = 25.0
    exposure_s: float = 0.008
    odom_hz: float = 100.0
    odom_noise: float = 0.01  # relative, per sample
    wheel_scale_error: tuple[float, float] = (0.004, -0.003)
    wheel_base_m: float = 0.42
    max_speed: float = 2.0
    drive_lag_s: float = 0.03
    mount_yaw_rad: float = 0.4
    mount_tilt_rad: tuple[float, float] = (0.012, -0.007)
    mount_offset_m: tuple[float, float] = (0.10, -0.03)
    mount_height_m: float = 0.35
    survey_sigma_m: float = 0.003
    spot_sigma_px: float = 1.6
    spot_peak: float = 420.0  # counts at 2.5 m on axis: the core saturates
    background: float = 22.0
    gain: float = 0.6  # counts per photo-electron (shot noise)
    read_noise: float = 2.5
    drop_frames: float = 0.0
    glints: tuple[tuple[float, float, float], ...] = ()  # (u / width, v / height, counts)
    # lights that are no landmark, fixed in the building: (x, y, z m, radius m, counts)
    stray_lights: tuple[tuple[float, float, float, float, float], ...] = ()
    # the robot lifted at `kidnap_s` and set down at `kidnap_to` (x, y, theta): the wheels
    # feel nothing of it; None: never
    kidnap_s: float | None = None
    kidnap_to: tuple[float, float, float] = (0.0, 0.0, 0.0)
    epoch_ns: int = 0  # the clock's origin: EuRoC's recordings count from 1970
    # the frames' stamps run this late against the odometry's clock (s): a stamp taken on
    # arrival instead of at the exposure's mid-point, or unsynchronised clocks
    camera_lag_s: float = 0.0
    odom_jitter_s: float = 0.0  # each odometry stamp late by up to this (uniform), s
    odom_burst: int = 1  # odometry samples reach the host (and are stamped) this many at once
    # wet patches: (x0, y0, x1, y1 m, left, right) where each wheel turns `left` / `right`
    # times faster than the floor moves under it (the odometry over-counts)
    slip_zones: tuple[tuple[float, float, float, float, float, float], ...] = ()
    # (start, end s): the robot stuck against an obstacle, its wheels turning as commanded
    stall_s: tuple[float, float] | None = None
    led_power: FloatArray = field(default_factory=lambda: np.ones(400))


def _turns(
    v: float, w: float, straight_s: float, angle: float
) -> tuple[tuple[float, float, float], ...]:
    return ((straight_s, v, 0.0), (0.25, 0.0, 0.0), (angle / w, 0.0, w), (0.25, 0.0, 0.0))


CASES: dict[str, Case] = {
    # a dense 40 cm grid, driving then spinning 180 deg at 3 rad/s, fisheye, 25 Hz / 100 Hz
    "grid40_spin": Case(
        grid(13, 9, 0.4, 2.7, 0.04), _turns(1.2, 3.0, 1.6, math.pi), start=(1.2, 1.6, 0.0)
    ),
    # EuRoC-like 752x480 wide radial-tangential lens, pairs with a gap, 20 Hz, 12 ms exposure
    "radtan_pairs": Case(
        corridor_pairs(2.9, 0.10),
        _turns(1.0, 2.0, 11.0, math.pi),
        start=(0.5, 0.1, 0.0),
        size=(752, 480),
        f_px=300.0,
        dist=(-0.28, 0.07, 0.0004, -0.0006),
        fisheye=False,
        rate_hz=20.0,
        exposure_s=0.012,
        odom_hz=40.0,
        mount_yaw_rad=math.pi / 2,
        mount_offset_m=(0.12, 0.0),
        spot_sigma_px=1.3,
        drop_frames=0.03,
        first_id=1,
    ),
    # an irregular ~1 m ceiling at 3.6 m, a square at 1.6 m/s with 90 deg turns at 2 rad/s
    "irregular_square": Case(
        irregular(8, 8, 1.0, 0.3, 3.6, 0.05),
        _turns(1.6, 2.0, 1.9, math.pi / 2),
        start=(2.0, 2.0, 0.0),
        f_px=230.0,
        rate_hz=30.0,
        exposure_s=0.015,
        odom_hz=50.0,
        spot_peak=300.0,
        mount_yaw_rad=-2.3,
        epoch_ns=1_403_636_579_763_555_584,
        first_id=1000,
    ),
    # sparse pairs along a 14 m corridor, fisheye, 1.5 m/s then half a turn at 3 rad/s
    "pairs_spin": Case(
        corridor_pairs(2.6, 0.05),
        _turns(1.5, 3.0, 4.0, math.pi),
        start=(0.3, -0.1, 0.0),
        rate_hz=30.0,
        odom_hz=50.0,
        f_px=240.0,
        mount_yaw_rad=-0.9,
        first_id=500,
    ),
    # a hall at 4.2 m, ~70 cm irregular grid with skylights: the robot is lifted after 10 s
    # and put down 4 m away turned by 100 deg; only the start-up sweep blinks (a replay)
    "hall_kidnap": Case(
        hall_with_skylights(0.7, 4.2, 0.06),
        ((3.0, 0.9, 0.25), (1.0, 0.0, 1.2), (3.0, 0.9, -0.25), (1.0, 0.0, -1.2)),
        start=(1.0, 1.0, 0.3),
        seconds=30.0,
        kidnap_s=10.0,
        kidnap_to=(5.2, 3.3, 2.0),
        f_px=250.0,
        rate_hz=30.0,
        exposure_s=0.01,
        odom_hz=50.0,
        mount_yaw_rad=2.9,
        first_id=2000,
    ),
    # an irregular 1.2 m ceiling with two lamps and a sunlit patch (no landmarks), a glint
    # beside a landmark's image, two dead LEDs, 5 % dropped frames
    "stray_light": Case(
        irregular(7, 6, 1.2, 0.25, 3.0, 0.04),
        ((4.0, 1.1, 0.3), (1.5, 0.0, 2.0), (4.0, 1.1, -0.3), (1.5, 0.0, -2.0)),
        start=(1.5, 1.5, 0.2),
        stray_lights=(
            (3.0, 2.4, 3.0, 0.15, 255.0),
            (5.5, 3.7, 3.0, 0.25, 180.0),
            (2.2, 4.5, 3.05, 0.6, 70.0),
        ),
        glints=((0.58, 0.41, 160.0),),
        drop_frames=0.05,
        led_power=np.concatenate([np.ones(9), [0.0], np.ones(20), [0.0], np.ones(400)]),
        first_id=700,
    ),
    # the paper's bed: three landmarks 1.2 m apart, a narrow pinhole lens, 10 deg steps
    "paper_bed": Case(
        triangle(1.2, 2.5),
        ((0.6, 0.0, 0.0), (math.radians(10) / 0.8, 0.0, 0.8)),
        start=(0.6, 0.35, 0.0),
        seconds=30.0,
        f_px=420.0,
        dist=(-0.06, 0.02, 0.0, 0.0),
        fisheye=False,
        rate_hz=15.0,
        exposure_s=0.02,
        odom_hz=100.0,
        mount_yaw_rad=0.0,
        mount_offset_m=(0.0, 0.0),
        mount_tilt_rad=(0.003, -0.002),
        survey_sigma_m=0.0,
        epoch_ns=1_764_547_200_000_000_000,
        first_id=1,
    ),
    # --- cases of the fourth pass (probe), none tuned on ---
    # the camera's stamps 30 ms late against the odometry (stamped on arrival); the odometry
    # at 50 Hz reaching the host three samples at a time, each stamp up to 4 ms late; an
    # irregular 0.8 m ceiling, 1.5 m/s legs with 2 rad/s turns and S-curves
    "clock_lag": Case(
        irregular(9, 7, 0.8, 0.2, 2.8, 0.04),
        (
            (2.5, 1.5, 0.0),
            (0.3, 0.0, 0.0),
            (math.pi / 2 / 2.0, 0.0, 2.0),
            (2.0, 1.2, 0.6),
            (2.0, 1.2, -0.6),
            (0.3, 0.0, 0.0),
            (math.pi / 2.0, 0.0, -2.0),
        ),
        start=(1.0, 1.0, 0.3),
        seconds=30.0,
        camera_lag_s=0.030,
        odom_hz=50.0,
        odom_burst=3,
        odom_jitter_s=0.004,
        rate_hz=30.0,
        f_px=250.0,
        mount_yaw_rad=1.2,
        first_id=3000,
    ),
    # a 2.2 m ceiling with a 55 cm grid at one end of a hall, none beyond it; a wide fisheye
    # at the robot's rear, yawed 180 deg, 30 cm behind the axle; the robot S-curves 8 m out
    # of the grid (dead reckoning), stops, reverses back into it (the re-entry: one grid
    # spacing is the ambiguity) and does it again
    "low_rear_reentry": Case(
        grid(9, 7, 0.55, 2.2, 0.02),
        (
            (3.0, 1.0, 0.0),
            (2.0, 1.0, 0.5),
            (2.0, 1.0, -0.5),
            (3.0, 1.0, 0.0),
            (0.6, 0.0, 0.0),
            (3.0, -1.0, 0.0),
            (2.0, -1.0, 0.5),
            (2.0, -1.0, -0.5),
            (3.4, -0.8, 0.0),
            (1.0, 0.0, 0.0),
            (math.pi / 2.5, 0.0, 2.5),
            (2.0, 0.6, 0.0),
            (math.pi / 2.5, 0.0, -2.5),
            (1.0, 0.0, 0.0),
        ),
        start=(0.5, 1.6, 0.0),
        seconds=36.0,
        f_px=185.0,
        dist=(0.02, -0.01, 0.004, -0.001),
        rate_hz=30.0,
        exposure_s=0.006,
        odom_hz=50.0,
        mount_yaw_rad=math.pi,
        mount_offset_m=(-0.30, 0.02),
        mount_height_m=0.40,
        spot_peak=300.0,
        first_id=4000,
    ),
    # a 7.5 m warehouse ceiling fitted out sparsely (landmarks >= 2.6 m apart), a narrow
    # 1280 x 960 lens (f 1100 px): 3-7 landmarks in view, small faint spots, survey 5 mm
    "high_narrow_sparse": Case(
        sparse(14.0, 10.0, 2.6, 7.5, 0.08),
        ((4.0, 1.0, 0.0), (0.5, 0.0, 0.0), (math.pi / 2 / 1.5, 0.0, 1.5), (0.5, 0.0, 0.0)),
        start=(4.0, 3.0, 0.1),
        seconds=24.0,
        size=(1280, 960),
        f_px=1100.0,
        dist=(-0.11, 0.09, 0.0003, -0.0002),
        fisheye=False,
        rate_hz=15.0,
        exposure_s=0.01,
        odom_hz=100.0,
        spot_sigma_px=1.0,
        spot_peak=900.0,
        mount_yaw_rad=-0.6,
        survey_sigma_m=0.005,
        first_id=5000,
    ),
    # a 12 Hz camera with a 20 ms exposure on a robot at 2 m/s, turns at 2.5 rad/s; a wet
    # patch where the left wheel spins 12 % and the right 6 % faster than the floor moves
    "fast_12hz_slip": Case(
        irregular(12, 8, 0.9, 0.2, 3.0, 0.05),
        (
            (3.0, 2.0, 0.0),
            (0.3, 0.0, 0.0),
            (math.pi / 2.5, 0.0, 2.5),
            (3.0, 2.0, 0.0),
            (0.3, 0.0, 0.0),
            (math.pi / 2.5, 0.0, -2.5),
        ),
        start=(1.0, 2.0, 0.0),
        seconds=30.0,
        rate_hz=12.0,
        exposure_s=0.020,
        odom_hz=50.0,
        max_speed=2.2,
        f_px=240.0,
        mount_yaw_rad=-1.9,
        slip_zones=((3.5, 1.0, 5.5, 3.0, 1.12, 1.06),),
        first_id=6000,
    ),
    # a hall half under a mezzanine (ceiling 2.6 m) and half open (5.2 m), 1280 x 800, LEDs
    # of unequal output: some near the detection threshold, some blooming
    "mezzanine_dim": Case(
        mezzanine(1.0, 2.6, 5.2, 5.0),
        ((6.0, 1.0, 0.0), (0.4, 0.0, 0.0), (math.pi / 1.5, 0.0, 1.5), (0.4, 0.0, 0.0)),
        start=(1.5, 3.0, 0.0),
        seconds=30.0,
        size=(1280, 800),
        f_px=420.0,
        fisheye=True,
        dist=(-0.01, 0.012, -0.006, 0.001),
        rate_hz=20.0,
        exposure_s=0.010,
        odom_hz=100.0,
        mount_yaw_rad=0.7,
        led_power=unequal_leds(400, 12),
        first_id=7000,
    ),
}
# the same building and robot, a wet patch in the landmark-free stretch (the left wheel
# spinning 3 % faster than the floor moves, out and back): the re-entry into the 55 cm grid
# comes back a large share of a spacing off, with an over-confident dead reckoning
CASES["reentry_slip"] = dataclasses.replace(
    CASES["low_rear_reentry"], slip_zones=((5.5, 0.5, 7.5, 4.5, 1.03, 1.0),), first_id=4500
)
# an irregular 0.8 m ceiling at 2.8 m, 30 Hz: the robot drives into a pallet at 0.8 m/s and
# is stuck for 1.5 s, its wheels turning (the odometry says it drove 1.2 m it did not)
CASES["stuck_wheels"] = dataclasses.replace(
    CASES["clock_lag"],
    segments=((3.0, 0.8, 0.0), (0.3, 0.0, 0.0), (math.pi / 2.0, 0.0, 2.0), (0.3, 0.0, 0.0)),
    start=(1.0, 1.5, 0.2),
    seconds=24.0,
    camera_lag_s=0.0,
    odom_burst=1,
    odom_jitter_s=0.0,
    stall_s=(6.5, 8.0),
    first_id=8000,
)
