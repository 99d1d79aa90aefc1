"""EKF fusing wheel odometry (eqs. 5-6) with landmark fixes, and learning the odometry's
systematic errors online (paper Sec. IV-B, taken past its hard switch).

State X = (x, y, theta, k_r, k_l, k_b): the body pose and three odometry calibration factors,
true right wheel speed = k_r v_r, true left = k_l v_l, true wheel base = k_b W (unequal wheel
radii and a wrong wheel base, the two dominant systematic errors of Borenstein's UMBmark). All
three are observable from fixes: driving straight shows (k_r - k_l) / k_b through the heading
drift and (k_r + k_l) / 2 through the distance, turning shows (k_r + k_l) / k_b.

The models (`motion_model`, `jacob_f`, `observation_model`, H = [I 0]) are in
`calibrated_odometry`, the tuning in `filter_config`; here are the predict and update
equations, written line for line like the math (PythonRobotics style).

The output can be smoothed (`output_state`): a fix moves the estimate at once, but the
output follows it with a time constant, so the reported pose has no jumps.

Speed: odometry arrives at 50-200 Hz, so `predict` works on Python floats (the covariance
too, as nested lists) and folds each step into a `DeferredPropagation`: the covariance of all
the steps since the last read is propagated at once, when next needed (an update, or a
read), with the composed Jacobian (`propagation.py`; exact, not an approximation).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from localizer.calibrated_odometry import (
    OdometryCalibration,
    Rows,
    State,
    motion_step,
    observation_model,
)
from localizer.filter_config import FilterConfig
from localizer.fix_bias import (
    carried_correlation,
    carry_bias,
    consider_update,
)
from localizer.geometry import wrap_angle
from localizer.odometry import odometry_partials
from localizer.pose import PoseFix
from localizer.propagation import DeferredPropagation
from localizer.small_linalg import inverse_3x3_sym
from localizer.types import FloatArray


class PoseFilter:
    """Extended Kalman filter over (x, y, theta, k_r, k_l, k_b).

    Args:
        x, y, theta: initial pose, metres and radians.
        covariance: of the initial pose, shape (3, 3).
        wheel_base: the configured wheel base W, metres.
        config: noise model; defaults to `FilterConfig()`.
    """

    def __init__(
        self,
        x: float,
        y: float,
        theta: float,
        covariance: npt.ArrayLike,
        *,
        wheel_base: float,
        config: FilterConfig | None = None,
    ) -> None:
        if not math.isfinite(wheel_base) or wheel_base <= 0:
            raise ValueError(f"PoseFilter: wheel_base must be positive metres, got {wheel_base!r}")
        self.config = config or FilterConfig()
        self.wheel_base = float(wheel_base)
        c = self.config
        # the noise densities squared, once (`predict` runs at the odometry's rate)
        self._noise2 = (
            c.wheel_noise_m_per_sqrt_s**2,
            c.wheel_slip_m_per_sqrt_m**2,
            c.calibration_walk_per_sqrt_s**2,
        )
        self._X: State = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
        k2 = self.config.calibration_prior_sigma**2 if self.config.estimate_calibration else 0.0
        # P as nested Python lists: for 6 states numpy's per-call overhead dominates
        self._P: Rows = [[k2 if i == j >= 3 else 0.0 for j in range(6)] for i in range(6)]
        self._offset = [0.0, 0.0, 0.0]  # output_state - state
        self._age_s = 0.0  # time since the last reset
        self._propagation = DeferredPropagation()
        self.noise_scale = 1.0  # odometry noise over the configured one (adapted online)
        self._turn_power = 0.0  # running mean of the measured turn rate squared, rad^2/s^2
        # cross-covariance of the state's error with the last fixes' systematic error, and
        # their landmarks (`fix_bias`); None: no correlated fix since the last reset
        self._C: Rows | None = None
        self._bias_ids: frozenset[int] = frozenset()
        self._bias_at = (0.0, 0.0)  # where the last of them was fused
        self._bias_R: Rows = [[0.0] * 3 for _ in range(3)]  # and that error's covariance
        self.reset(x, y, theta, covariance)

    # -- state ----------------------------------------------------------------------------------
    @property
    def state(self) -> FloatArray:
        """The estimated pose (x, y, theta), shape (3,)."""
        return np.array(self._X[:3])

    @property
    def pose(self) -> tuple[float, float, float]:
        """The estimated pose (x, y, theta) as floats (`state` without the array)."""
        x, y, theta = self._X[:3]
        return x, y, theta

    @property
    def covariance(self) -> FloatArray:
        """Covariance of (x, y, theta), shape (3, 3) (a copy)."""
        self._flush()
        P = self._P
        return np.array([P[0][:3], P[1][:3], P[2][:3]])

    @property
    def covariance_rows(self) -> tuple[list[float], list[float], list[float]]:
        """`covariance` as three rows of floats (no array; do not modify them)."""
        self._flush()
        P0, P1, P2 = self._P[0], self._P[1], self._P[2]
        return P0[:3], P1[:3], P2[:3]

    @property
    def full_state(self) -> FloatArray:
        """(x, y, theta, k_r, k_l, k_b), shape (6,)."""
        return np.array(self._X)

    @property
    def full_covariance(self) -> FloatArray:
        """Covariance of `full_state`, shape (6, 6) (a copy)."""
        self._flush()
        return np.array(self._P)

    @property
    def output_state(self) -> FloatArray:
        """The smoothed pose for output, (x, y, theta) shape (3,): follows `state` without
        jumps (time constant `config.output_time_constant_s`)."""
        return np.array(self.output_pose)

    @property
    def output_pose(self) -> tuple[float, float, float]:
        """`output_state` as floats, heading wrapped to (-pi, pi]."""
        (x, y, th), (ox, oy, oth) = self._X[:3], self._offset
        return x + ox, y + oy, float(wrap_angle(th + oth))

    @property
    def calibration(self) -> OdometryCalibration:
        """The estimated odometry factors."""
        self._flush()
        k_r, k_l, k_b = self._X[3:]
        return OdometryCalibration(k_r, k_l, k_b, np.array([r[3:] for r in self._P[3:]]))

    def reset(self, x: float, y: float, theta: float, covariance: npt.ArrayLike) -> None:
        """Restart from a pose; keeps the calibration learnt so far (and its covariance)."""
        cov = np.asarray(covariance, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise ValueError(f"PoseFilter.reset: covariance must be finite (3, 3), got {cov.shape}")
        if not all(math.isfinite(v) for v in (x, y, theta)):
            raise ValueError(f"PoseFilter.reset: non-finite pose {(x, y, theta)}")
        self._flush()
        self._X[:3] = [float(x), float(y), float(wrap_angle(theta))]
        sym = (0.5 * (cov + cov.T)).tolist()
        self._P = [sym[i] + [0.0] * 3 for i in range(3)] + [
            [0.0, 0.0, 0.0, *row[3:]] for row in self._P[3:]
        ]
        self._offset = [0.0, 0.0, 0.0]
        self._age_s = 0.0
        self._C, self._bias_ids = None, frozenset()

    def copy(self) -> PoseFilter:
        """An independent copy (state, covariance, output offset): a frame's tentative
        filter, extrapolated past the last odometry sample and kept only if a fix is fused.
        The deferred propagation is copied, not applied: the copy applies it with its own
        steps in one go (a frame pays for one propagation, not two)."""
        twin = object.__new__(PoseFilter)
        twin.config, twin.wheel_base, twin._noise2 = self.config, self.wheel_base, self._noise2
        twin._X = list(self._X)
        twin._P = [list(r) for r in self._P]
        twin._offset = list(self._offset)
        twin._age_s = self._age_s
        twin._propagation = self._propagation.copy()
        twin.noise_scale = self.noise_scale
        twin._turn_power = self._turn_power
        twin._C = self._C  # (never modified in place: each step builds a new one)
        twin._bias_ids, twin._bias_at, twin._bias_R = self._bias_ids, self._bias_at, self._bias_R
        return twin

    def inflate(self, var_xy_m2: float, var_theta_rad2: float) -> None:
        """Add independent variance to the pose: an unmodelled motion (e.g. the wheel speeds
        may have changed since the last odometry sample)."""
        self._flush()
        self._P[0][0] += var_xy_m2
        self._P[1][1] += var_xy_m2
        self._P[2][2] += var_theta_rad2

    def shift(self, dx_m: float, dy_m: float, dtheta_rad: float) -> None:
        """Move the pose estimate (and the output with it) by a known amount: the same fixes
        read through a corrected camera calibration (`online_calibration`) put the robot
        there. The covariance stays."""
        X = self._X
        X[0] += dx_m
        X[1] += dy_m
        X[2] = float(wrap_angle(X[2] + dtheta_rad))

    def snap_output(self) -> None:
        """Let the output take the estimate at once (no smoothing of the last correction):
        for a correction of motion the prediction did not know of (a turn begun after the
        last odometry sample), which smoothing would only turn into a lag."""
        self._offset = [0.0, 0.0, 0.0]

    # -- predict --------------------------------------------------------------------------------
    def predict(self, v_left: float, v_right: float, dt: float) -> None:
        """Dead-reckon over `dt` seconds with the measured wheel speeds (m/s); any rate.

        X = f(X, u);  P = F P F^T + G M G^T + Q_walk  (P deferred, see the module doc).
        """
        if dt <= 0:
            return
        cfg = self.config
        X = self._X
        self._X, F_top, G = motion_step(X, v_left, v_right, dt, self.wheel_base)
        # M: variance of each wheel's true speed, from its travel's noise over the step
        k2 = self.noise_scale * self.noise_scale
        noise2, slip2, walk2 = self._noise2
        q2, s2 = k2 * noise2 * dt, k2 * slip2
        m_l = (q2 + s2 * abs(X[4] * v_left * dt)) / (dt * dt)
        m_r = (q2 + s2 * abs(X[3] * v_right * dt)) / (dt * dt)
        if cfg.attenuate_turn_scale:
            # The wheel base's column of F scales the measured turn dR, noise included:
            # driving straight, dR is the wheels' noise alone, the heading error it causes
            # and the column share it, and every fix then pushed k_b up (by the noise's
            # variance: 3 % in 15 s, so the next 180 deg turn was 5 deg off). Evaluated at
            # the expected true turn given the measured one, dR w^2 / (w^2 + var(r)), w^2
            # the true turn rate's prior variance: the mean square of the turn rates
            # measured before (less their noise's variance), so that the shrink does not
            # depend on this step's noise (with w^2 = r^2, this step's own rate, the
            # product f dR still is odd in its noise, and k_b was still pushed up, by about
            # half: `test_fix_bias.py`).
            W = X[5] * self.wheel_base
            r = (X[3] * v_right - X[4] * v_left) / W  # the measured turn rate
            var_r = (m_l + m_r) / (W * W)
            tau = cfg.turn_power_time_constant_s
            if tau > 0:
                w2 = max(self._turn_power - var_r, 0.0)
                self._turn_power += min(dt / tau, 1.0) * (r * r - self._turn_power)
            else:
                w2 = r * r
            f = w2 / (w2 + var_r) if var_r > 0 else 1.0
            F_top[0][5] *= f
            F_top[1][5] *= f
            F_top[2][5] *= f

        walk = walk2 * dt if cfg.estimate_calibration else 0.0
        self._propagation.add_step(F_top, G, m_l, m_r, walk)

        self._age_s += dt
        if cfg.output_time_constant_s > 0:
            decay = math.exp(-dt / cfg.output_time_constant_s)
            o0, o1, o2 = self._offset
            self._offset = [o0 * decay, o1 * decay, o2 * decay]
        else:
            self._offset = [0.0, 0.0, 0.0]

    def predict_motion(
        self, v: float, w: float, dt: float, var_xy_m2: float, var_theta_rad2: float
    ) -> None:
        """Predict over `dt` seconds without odometry: the pose moves along the arc of the
        motion model (`motion_model`: forward speed `v` m/s, turn rate `w` rad/s; eq. (5)
        with dT = v dt, dR = w dt, the arc's midpoint heading), and the model's process
        noise is added: P_pose = F P_pose F^T + Q, Q = diag(var_xy, var_xy, var_theta). The
        odometry calibration factors take no part (their rows and columns are carried by F).
        """
        if dt <= 0:
            return
        self._flush()
        x, y, th = self._X[:3]
        dT, dR = v * dt, w * dt
        # the exact arc (its chord), as `integrate_arc`
        chord = 2.0 * math.sin(0.5 * dR) / dR if abs(dR) > 1e-9 else 1.0
        xT, yT, xR, yR = odometry_partials(th, dT * chord, dR)
        self._X[:3] = [x + dT * chord * xT, y + dT * chord * yT, float(wrap_angle(th + dR))]
        F = np.eye(6)
        F[0, 2], F[1, 2] = 2.0 * xR, 2.0 * yR
        P = F @ np.array(self._P) @ F.T
        P[0, 0] += var_xy_m2
        P[1, 1] += var_xy_m2
        P[2, 2] += var_theta_rad2
        self._P = (0.5 * (P + P.T)).tolist()
        if self._C is not None:
            self._C = (F @ np.array(self._C)).tolist()
        self._age_s += dt
        if self.config.output_time_constant_s > 0:
            decay = math.exp(-dt / self.config.output_time_constant_s)
            self._offset = [o * decay for o in self._offset]
        else:
            self._offset = [0.0, 0.0, 0.0]

    def _flush(self) -> None:
        """Apply the deferred covariance propagation (see `DeferredPropagation`)."""
        if self._propagation.pending:
            if self._C is not None:
                self._C = self._propagation.carry(self._C)
            self._P = self._propagation.apply(self._P)

    # -- update ---------------------------------------------------------------------------------
    def _innovation(self, fix: PoseFix) -> tuple[list[float], list[float] | None]:
        """y = z - h(X), heading wrapped; S^-1 of S = H P H^T + R (6 numbers, None if singular)."""
        self._flush()
        x, y, th = observation_model(self._X)
        innovation = [fix.x - x, fix.y - y, float(wrap_angle(fix.theta - th))]
        P0, P1, P2 = self._P[0], self._P[1], self._P[2]
        (r00, r01, r02), (_, r11, r12), (_, _, r22) = np.asarray(fix.covariance).tolist()
        S_inv = inverse_3x3_sym(
            [P0[0] + r00, P0[1] + r01, P0[2] + r02, P1[1] + r11, P1[2] + r12, P2[2] + r22]
        )
        return innovation, S_inv

    def nis(self, fix: PoseFix) -> float:
        """Normalised innovation squared y^T S^-1 y of a fix (chi-square, 3 dof), not applied."""
        y, S_inv = self._innovation(fix)
        return _quadratic_form(y, S_inv)

    def update_fix(
        self,
        fix: PoseFix,
        *,
        max_nis: float | None = None,
        white_covariance: FloatArray | None = None,
    ) -> float:
        """Fuse a landmark fix (measurement (x, y, theta) with `fix.covariance`).

        y = z - h(X);  S = H P H^T + R;  K = P H^T S^-1;  X = X + K y;  P = (I - K H) P.

        With `white_covariance` the fix's covariance is split (`fix_bias`): that part is
        white (new on every frame), the rest systematic (survey, calibration), the same for
        every fix of the same landmarks. The update is then the consider update, which
        carries the state's correlation with that error from fix to fix.

        Args:
            fix: the fix.
            max_nis: when given, a fix whose NIS exceeds it is not applied (gate); e.g. the
                chi-square 3-dof 99.9 % quantile 16.27.
            white_covariance: the white part of `fix.covariance`, (3, 3).

        Returns:
            The fix's NIS (normalised innovation squared) before the update; inf (and the
            fix not applied) when S is singular.
        """
        if white_covariance is not None:
            ids = frozenset(fix.landmark_ids)
            found = self._consider_step(fix, white_covariance, ids)
            if found is None:
                return math.inf
            dX, P_new, C_new, nis, R_bias = found
            if max_nis is not None and not nis <= max_nis:
                return nis
            self._P, self._C = P_new, C_new
            self._bias_ids, self._bias_at = ids, (fix.x, fix.y)
            self._bias_R = R_bias
        else:
            y, S_inv = self._innovation(fix)
            nis = _quadratic_form(y, S_inv)
            if S_inv is None or (max_nis is not None and not nis <= max_nis):
                return nis
            dX = self._plain_step(y, S_inv)
            self._C, self._bias_ids = None, frozenset()
        self._apply_correction(dX, nis)
        return nis

    def _consider_step(
        self, fix: PoseFix, white: FloatArray, ids: frozenset[int]
    ) -> tuple[list[float], Rows, Rows, float, Rows] | None:
        """The consider update's correction, covariance, cross-covariance and NIS, and the
        fix's systematic covariance (not applied); None when S is singular. Plain floats."""
        self._flush()
        x, y, th = observation_model(self._X)
        innovation = [fix.x - x, fix.y - y, float(wrap_angle(fix.theta - th))]
        R_white = white.tolist()
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = fix.covariance.tolist()
        (w00, w01, w02), (w10, w11, w12), (w20, w21, w22) = R_white
        R_bias = [
            [r00 - w00, r01 - w01, r02 - w02],
            [r10 - w10, r11 - w11, r12 - w12],
            [r20 - w20, r21 - w21, r22 - w22],
        ]
        rho = carried_correlation(self._bias_ids, ids)
        C = None
        if self._C is not None and rho > 0.0:
            dx, dy = fix.x - self._bias_at[0], fix.y - self._bias_at[1]
            C = carry_bias(self._C, self._bias_R, R_bias, rho, dx, dy)
        # (rounding can still leave the joint covariance a hair from positive definite:
        # then the correlation is shrunk, and at last dropped)
        for shrink in (1.0, 0.5, 0.0):
            if C is None or shrink == 0.0:
                Cs = [[0.0, 0.0, 0.0] for _ in range(6)]
            else:
                Cs = C if shrink == 1.0 else [[shrink * v for v in row] for row in C]
            found = consider_update(self._P, Cs, innovation, R_white, R_bias)
            if found is not None:
                dX, P_new, C_new, nis = found
                return dX, P_new, C_new, nis, R_bias
            if C is None:
                break
        return None

    def _plain_step(self, y: list[float], S_inv: list[float]) -> list[float]:
        """The ordinary update: P applied, the state's correction returned."""
        # Plain floats: for a 6-state filter numpy's per-call overhead dominates.
        i00, i01, i02, i11, i12, i22 = S_inv
        P = self._P
        P0, P1, P2 = P[0], P[1], P[2]  # H P = P[:3, :]
        y0, y1, y2 = y
        dX = []
        new = [[0.0] * 6 for _ in range(6)]  # P - K H P, the upper triangle mirrored (symmetric)
        for i, row in enumerate(P):
            a, b, c = row[0], row[1], row[2]
            k0 = a * i00 + b * i01 + c * i02  # the row of K = P H^T S^-1 = P[:, :3] S^-1
            k1 = a * i01 + b * i11 + c * i12
            k2 = a * i02 + b * i12 + c * i22
            dX.append(k0 * y0 + k1 * y1 + k2 * y2)
            out = new[i]
            for j in range(i, 6):
                out[j] = new[j][i] = row[j] - (k0 * P0[j] + k1 * P1[j] + k2 * P2[j])
        self._P = new
        return dX

    def _apply_correction(self, dX: list[float], nis: float) -> None:
        """Move the state by a fused fix's correction; adapt the odometry noise from its
        NIS; the output offset (smoothing)."""
        old = self._X
        X = [u + d for u, d in zip(old, dX, strict=True)]
        X[2] = float(wrap_angle(X[2]))
        lo, hi = self.config.calibration_bounds
        X[3], X[4], X[5] = min(max(X[3], lo), hi), min(max(X[4], lo), hi), min(max(X[5], lo), hi)
        self._X = X

        if self.config.adapt_noise:
            lo_s, hi_s = self.config.noise_scale_bounds
            k2 = self.noise_scale**2 * (1.0 + self.config.adapt_gain * (min(nis, 30.0) / 3 - 1))
            self.noise_scale = min(max(math.sqrt(max(k2, 0.0)), lo_s), hi_s)
        jump = [old[0] - X[0], old[1] - X[1], float(wrap_angle(old[2] - X[2]))]
        settling = self._age_s < self.config.output_settle_s
        if settling or math.hypot(jump[0], jump[1]) > self.config.output_snap_m:
            self._offset = [0.0, 0.0, 0.0]
        else:
            self._offset = [o + j for o, j in zip(self._offset, jump, strict=True)]


def _quadratic_form(y: list[float], S_inv: list[float] | None) -> float:
    """y^T S^-1 y for S^-1 given as (s00 s01 s02 s11 s12 s22); inf when S is singular."""
    if S_inv is None:
        return math.inf
    i00, i01, i02, i11, i12, i22 = S_inv
    a, b, c = y
    return i00 * a * a + i11 * b * b + i22 * c * c + 2.0 * (i01 * a * b + i02 * a * c + i12 * b * c)
