"""Issue 12's cases (1)-(4) as `Case`s (tests/localizer/cases.py), and a printout:

PYTHONPATH=$PWD .venv/bin/python -m tests.localizer.issue12_cases [NAME ...]
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable

import numpy as np

from localizer.camera import T_body_camera_upward
from tests.localizer.cases import (
    Case,
    Path,
    drive_then_turn,
    fisheye_camera,
    grid_positions,
    heading_sweep,
    irregular_positions,
    miscalibrated,
    pair_positions,
    run_case,
    strong_radtan_camera,
    surveyed,
)


def dense_turn(seed: int = 1, *, calibration_error: bool = True, omega: float = 3.0) -> Case:
    """(1) A 12 x 8 grid 40 cm apart, fisheye; drive at 1 m/s, then turn in place at 3 rad/s."""
    rng = np.random.default_rng(seed)
    truth = grid_positions(12, 8, 0.4, 2.5)
    true_cam = fisheye_camera(T_body_camera_upward(height=0.3))
    cam = miscalibrated(true_cam, rng) if calibration_error else true_cam
    start = (0.6, 1.4, 0.0)
    path = Path.from_segments(start, drive_then_turn(start, v=1.0, drive_s=2.0, omega=omega,
                                                     turn_s=1.5, repeats=3))  # fmt: skip
    return Case("dense_turn", true_cam, cam, truth, surveyed(truth, rng), path, seed=seed,
                prior=start)  # fmt: skip


def sparse_turn(seed: int = 2, *, omega: float = 3.0) -> Case:
    """(1) An irregular ceiling about 1 m apart, +-12 cm heights; drive, then turn in place."""
    rng = np.random.default_rng(seed)
    truth = irregular_positions(rng, 0, (6.0, 3.0), spacing=1.0)
    true_cam = fisheye_camera(T_body_camera_upward(height=0.3))
    cam = miscalibrated(true_cam, rng)
    start = (1.0, 1.5, 0.0)
    path = Path.from_segments(start, drive_then_turn(start, v=1.2, drive_s=1.6, omega=omega,
                                                     turn_s=1.5, repeats=3))  # fmt: skip
    return Case("sparse_turn", true_cam, cam, truth, surveyed(truth, rng), path, seed=seed,
                prior=start)  # fmt: skip


def hostile_lens(seed: int = 3) -> Case:
    """(2) Strong radial-tangential lens, camera yawed 90 deg 12 cm ahead, uneven ceiling,
    landmark pairs with gaps, realistic calibration error; a patrol with turns."""
    rng = np.random.default_rng(seed)
    centres = [
        (x, y, a)
        for x, y, a in [
            (0.0, 0.0, 0.0),
            (1.6, 0.2, 1.2),
            (3.1, -0.1, 0.4),
            (4.8, 0.1, 2.0),
            (6.3, 0.0, 0.9),
            (0.2, 1.7, 2.6),
            (3.2, 1.8, 0.1),
            (6.1, 1.6, 1.9),
        ]
    ]
    truth = pair_positions(centres, gap=0.5, z=2.5, z_jitter=0.12, rng=rng)
    T = T_body_camera_upward(yaw=math.pi / 2, offset_xy=(0.12, 0.0), height=0.3)
    true_cam = strong_radtan_camera(T)
    cam = miscalibrated(true_cam, rng)
    start = (0.0, 0.5, 0.0)
    segs = [
        (1.0, 0.0, 0.0),
        (5.0, 0.6, 0.0),
        (1.0, 0.0, math.pi / 2),
        (2.0, 0.6, 0.0),
        (1.0, 0.0, math.pi / 2),
        (5.0, 0.6, 0.0),
        (1.0, 0.0, math.pi / 2),
        (1.5, 0.6, 0.0),
    ]
    return Case("hostile_lens", true_cam, cam, truth, surveyed(truth, rng, 0.005),
                Path.from_segments(start, segs), seed=seed, prior=start)  # fmt: skip


def paper_testbed(seed: int = 4) -> Case:
    """(3) Three landmarks 120 cm apart, turned on the spot in 10 deg steps."""
    rng = np.random.default_rng(seed)
    truth = np.array([[0.0, 0.0, 2.5], [1.2, 0.0, 2.5], [0.6, 1.0392, 2.5]])
    true_cam = strong_radtan_camera(T_body_camera_upward(height=0.3))
    cam = miscalibrated(true_cam, rng)
    start = (0.6, 0.35, 0.0)
    return Case("paper_testbed", true_cam, cam, truth, truth.copy(),
                Path.from_segments(start, heading_sweep(steps=36)), seed=seed,
                max_speed=1.0, odom_noise_m_s=0.01)  # fmt: skip


def kidnap(seed: int = 5, *, leds: bool = True) -> Case:
    """A robot on the dense grid lifted and put down 1.3 m away, turned by 1 rad."""
    c = dense_turn(seed, omega=1.0)
    start = (0.6, 1.4, 0.0)
    segs = [(0.5, 0.0, 0.0), (2.0, 0.5, 0.0), (1.0, 0.0, 0.0), (12.0, 0.0, 0.3)]
    c.path = Path.from_segments(start, segs)
    c.name = "kidnap_leds" if leds else "kidnap_no_leds"
    c.kidnap = (3.0, 1.3, 0.4, 1.0)
    c.leds_controllable = leds
    return c


def kidnap_irregular(seed: int = 7) -> Case:
    """No LED control, a dense irregular ceiling (about 50 cm apart, +-12 cm heights): the
    robot is lifted and put down 1.3 m away, turned by 1 rad."""
    rng = np.random.default_rng(seed)
    truth = irregular_positions(rng, 0, (5.0, 3.5), spacing=0.5)
    true_cam = fisheye_camera(T_body_camera_upward(height=0.3))
    cam = miscalibrated(true_cam, rng)
    start = (1.0, 1.5, 0.0)
    segs = [(0.5, 0.0, 0.0), (2.0, 0.5, 0.0), (1.0, 0.0, 0.0), (12.0, 0.0, 0.3)]
    return Case("kidnap_irregular", true_cam, cam, truth, surveyed(truth, rng),
                Path.from_segments(start, segs), seed=seed, prior=start,
                leds_controllable=False, kidnap=(3.0, 1.3, 0.4, 1.0))  # fmt: skip


def no_leds_dense(seed: int = 6) -> Case:
    """(4) LEDs cannot be switched (a replay): a prior 20 cm off, then turns."""
    c = dense_turn(seed)
    c.name = "no_leds_dense"
    c.leds_controllable = False
    c.prior = (0.75, 1.3, 0.1)
    return c


CASES: dict[str, Callable[[], Case]] = {
    "dense_turn": dense_turn,
    "sparse_turn": sparse_turn,
    "hostile_lens": hostile_lens,
    "paper_testbed": paper_testbed,
    "kidnap_leds": lambda: kidnap(leds=True),
    "kidnap_no_leds": lambda: kidnap(leds=False),
    "kidnap_irregular": kidnap_irregular,
    "no_leds_dense": no_leds_dense,
}


def main(argv: list[str]) -> int:
    for name in argv or list(CASES):
        t0 = time.perf_counter()
        run = run_case(CASES[name]())
        print(f"{name:<16}{run.summary()}  ({time.perf_counter() - t0:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
