"""The 95 % radius, the 0-1 quality and the published covariance (`localizer.pose_quality`)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from localizer.pose_quality import (
    QualityConfig,
    circle_probability,
    deviation_radius_m,
    heading_deviation_rad,
    published_covariance,
    quality_from_deviation,
)


@pytest.mark.parametrize("ratio", [0.0, 0.05, 0.33, 0.5, 0.71, 0.9, 0.97, 1.0])
def test_tabulated_radius_is_the_root_of_the_circle_probability(ratio: float) -> None:
    sd_minor = max(ratio, 1e-6)
    root = brentq(lambda r: circle_probability(r, 1.0, sd_minor) - 0.95, 1.9, 2.5, xtol=1e-9)
    assert deviation_radius_m(np.diag([1.0, sd_minor**2])) == pytest.approx(root, rel=5e-4)


def test_the_circle_holds_95_percent_of_a_rotated_anisotropic_error() -> None:
    rng = np.random.default_rng(7)
    a = 0.6
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    P = R @ np.diag([0.04**2, 0.015**2]) @ R.T
    e = rng.multivariate_normal([0.0, 0.0], P, size=400_000)
    r = deviation_radius_m(P)
    assert np.mean(np.hypot(e[:, 0], e[:, 1]) <= r) == pytest.approx(0.95, abs=0.002)


def test_radius_limits_and_bad_input() -> None:
    assert deviation_radius_m(np.diag([0.01**2, 0.01**2, 1.0])) == pytest.approx(
        0.0244775, rel=1e-5
    )
    assert deviation_radius_m(np.diag([0.01**2, 0.0])) == pytest.approx(0.0196, rel=1e-4)
    assert deviation_radius_m(np.diag([0.0, 0.01**2])) == pytest.approx(0.0196, rel=1e-4)
    assert deviation_radius_m(np.zeros((2, 2))) == 0.0
    with pytest.raises(ValueError, match="non-finite"):
        deviation_radius_m(np.array([[np.nan, 0.0], [0.0, 1.0]]))


def test_heading_bound() -> None:
    assert heading_deviation_rad(np.diag([1.0, 1.0, 0.01**2])) == pytest.approx(0.0196, rel=1e-4)


def test_quality_is_logarithmic_between_good_and_useless() -> None:
    c = QualityConfig(good_m=0.02)
    assert quality_from_deviation(0.01, c) == 1.0
    assert quality_from_deviation(0.02, c) == 1.0
    assert quality_from_deviation(0.10, c) == pytest.approx(1 - math.log(5) / math.log(50))
    assert quality_from_deviation(0.05, QualityConfig()) == pytest.approx(0.8543, abs=1e-4)
    assert quality_from_deviation(1.0, c) == 0.0
    assert quality_from_deviation(3.0, c) == 0.0
    assert quality_from_deviation(None, c) == 0.0
    qs = [quality_from_deviation(d, c) for d in np.geomspace(0.02, 1.0, 20)]
    assert all(a > b for a, b in itertools.pairwise(qs))
    with pytest.raises(ValueError, match="good_m < useless_m"):
        QualityConfig(good_m=0.5, useless_m=0.1)


def test_published_covariance_scales_floors_and_adds_the_output_offset() -> None:
    P = np.diag([1e-4, 4e-4, 1e-6])
    cfg = QualityConfig(
        position_scale={"landmark": 2.0},
        heading_scale={"landmark": 3.0},
        position_floor_m={"landmark": 0.01},
        heading_floor_rad={"landmark": 0.001},
    )
    out = published_covariance(P, "landmark", (0.003, 0.0, 0.0), cfg)
    np.testing.assert_allclose(
        out, np.diag([4e-4 + 1e-4 + 9e-6, 16e-4 + 1e-4, 9e-6 + 1e-6]), rtol=1e-12
    )
    # a mode left out keeps the filter's covariance (plus the offset)
    only = QualityConfig(position_scale={}, heading_scale={}, position_floor_m={},
                         heading_floor_rad={})  # fmt: skip
    np.testing.assert_allclose(published_covariance(P, "dead_reckoning", (0, 0, 0), only), P)
    # the defaults: scale 2 and a 2 cm floor in dead reckoning
    d = published_covariance(P, "dead_reckoning", (0, 0, 0), QualityConfig())
    np.testing.assert_allclose(np.diag(d)[:2], [4e-4 + 4e-4, 16e-4 + 4e-4])
    with pytest.raises(ValueError, match="position_scale"):
        QualityConfig(position_scale={"landmark": 0.0})
    with pytest.raises(ValueError, match=r"\(3, 3\)"):
        published_covariance(np.eye(2), "landmark", (0, 0, 0), cfg)
