"""The buildings of the independent generator (`bench/foreign/generate.py`): chosen unlike
our own simulator's defaults on purpose (camera and odometry rates, resolutions, exposure
blur, spot shape, noise, ceiling heights, speeds), never tuned to pass."""

from __future__ import annotations

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
}
