"""The pose filter's noise model and tuning (`FilterConfig`, SI units; `pose_filter`)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class FilterConfig:
    """Noise model and tuning of `PoseFilter` (SI units).

    Attributes:
        wheel_noise_m_per_sqrt_s: white noise on each wheel's measured travel, metres per
            sqrt(second) (the speed noise's spectral density, (m/s)/sqrt(Hz)): over a step
            dt a wheel's travel has variance wheel_noise^2 dt, whatever the odometry rate.
        wheel_slip_m_per_sqrt_m: travel noise growing with distance (slip, uneven floor):
            variance wheel_slip^2 |travel| per wheel.
        calibration_walk_per_sqrt_s: random walk of each calibration factor, 1/sqrt(s)
            (lets the estimate follow slow changes: load, tyre wear).
        calibration_prior_sigma: prior standard deviation of each factor around 1.
        estimate_calibration: learn (k_r, k_l, k_b) from the fixes; False freezes them at
            their current value (1 at start).
        calibration_bounds: the factors are kept inside these bounds.
        output_time_constant_s: how fast `output_state` follows a correction, seconds
            (0: no smoothing).
        output_snap_m: a correction larger than this (a relocalisation) is not smoothed.
        output_settle_s: for this long after `reset` (a first fix, a relocalisation) the
            output takes corrections at once: the refinements of a fresh estimate (e.g. a
            third landmark after a first fix from two) are not smoothed into a slow drift.
        adapt_noise: adapt the odometry noise (`noise_scale`, a factor on both noise
            terms) from the fused fixes' NIS: a running estimate of NIS / 3 (1 when the
            filter's predicted covariance is right); the configured values are the prior.
        adapt_gain: weight of one fix in that running estimate.
        noise_scale_bounds: the factor stays within these.
        attenuate_turn_scale: evaluate the wheel base's Jacobian at the expected true turn
            given the measured one (the measured turn's noise otherwise biases k_b upwards
            while driving straight; see `predict`).
        turn_power_time_constant_s: the expected true turn rate's prior variance is
            estimated from the measured turn rates of the samples before, averaged with
            this time constant, seconds (empirical Bayes: driving straight it is the
            wheels' noise alone, so the wheel base's Jacobian is shrunk to nearly zero; in
            a turn it is the turn's own). 0: from the step's own measured turn (a partial
            shrink: that turn's noise is the heading error it causes).
    """

    wheel_noise_m_per_sqrt_s: float = 0.003
    wheel_slip_m_per_sqrt_m: float = 0.002
    calibration_walk_per_sqrt_s: float = 1e-5
    calibration_prior_sigma: float = 0.03
    estimate_calibration: bool = True
    calibration_bounds: tuple[float, float] = (0.8, 1.2)
    output_time_constant_s: float = 0.05
    output_snap_m: float = 0.5
    output_settle_s: float = 1.0
    adapt_noise: bool = True
    adapt_gain: float = 0.005
    noise_scale_bounds: tuple[float, float] = (0.7, 4.0)
    attenuate_turn_scale: bool = True
    turn_power_time_constant_s: float = 0.25

    def __post_init__(self) -> None:
        for name in (
            "wheel_noise_m_per_sqrt_s",
            "wheel_slip_m_per_sqrt_m",
            "calibration_walk_per_sqrt_s",
            "output_time_constant_s",
            "output_settle_s",
            "turn_power_time_constant_s",
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"FilterConfig: {name} must be >= 0, got {v!r}")
        for name in ("calibration_prior_sigma", "output_snap_m"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"FilterConfig: {name} must be > 0, got {v!r}")
        lo, hi = self.calibration_bounds
        if not 0 < lo < 1 < hi:
            raise ValueError(
                f"FilterConfig: calibration_bounds must satisfy 0 < lo < 1 < hi, got {(lo, hi)}"
            )
