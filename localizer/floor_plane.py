"""The floor under the robot: its height and slope, a slowly varying state carried from fix to
fix.

The map's landmark heights are above the floor the camera's mounting height refers to; a real
floor is neither level nor at one height. Where the robot stands, the floor is locally the
plane of height h (metres, above the map's z = 0) and world gradient g = (dh/dx, dh/dy)
(dimensionless). A body on it at heading theta is raised by h and tilted with it:

    g_b = Rz(theta)^T g,    pitch = -atan(g_b,x),    roll = atan(g_b,y)             (1)

(REP-103: + pitch is nose down, so going uphill pitches the nose up; + roll is the left side
down; R_world_body = Rz(theta) Ry(pitch) Rx(roll), as `pose_tilted` and the simulator have
it). For the slopes of a building (a few degrees) the map from g to the body tilt
t = (roll, pitch) is, to first order, the orthogonal

    t = M(theta) g,    M(theta) = [[-sin theta, cos theta], [-cos theta, -sin theta]],   (2)

so the fix's extra unknowns e = (roll, pitch, dz) are e = B(theta) s of the state
s = (h, gx, gy), with B = [[0, M], [1, 0]] orthogonal too: a covariance P of s is B P B^T
of e and back (B^-1 = B^T). dz is the camera's height above where the mounting puts it,
i.e. the floor's height h.

The floor is a property of the place, not of the robot: its slope stays when the robot turns
(the body tilt it causes turns with the heading, eq. 1) and changes only along the floor. So
the state is carried in the world frame, predicted from the position p0 of its last update to
the position p a distance d = |p - p0| away by the plane itself, returning to the map's level
floor over a length L (a first-order Gauss-Markov process whose stationary covariance is the
prior's, P0: a ramp ends, a floor is level on the whole) plus a random walk for its changes:

    s <- a F s,   P <- a^2 F P F^T + (1 - a^2) P0 + d Q,   a = exp(-d / L),           (3)

F = [[1, (p - p0)^T], [0, I]], Q = diag(sigma_h^2, sigma_g^2, sigma_g^2) per metre
(`level_length_m`, `change_*_per_sqrt_m`), and a fix updates it where its spots demand a
floor of their own.

Each fix of 3+ landmarks is first solved on the carried floor (at its mean e0 = B s). Only
when a tilted fit explains the spots better by a likelihood-ratio test (`solve_pose`:
chi-square lower by more than 9.21, the 99 % point with 2 dof) does it estimate the floor; that
fit uses a wide prior W around e0 (`change_slope`, `change_sigma_m`: a floor may have changed
under the robot, a ramp, a bump), giving the posterior (e_w, C_w). The frame's own information
on e is then I = C_w^-1 - W^-1, and the carried belief (e0, Pc) is updated by it (a Kalman
update in information form, no inverse of the possibly singular I needed):

    Pf^-1 = Pc^-1 + I,    Pf^-1 e_f = Pc^-1 e0 + C_w^-1 e_w - W^-1 e0,                 (4)

unless the frame disagrees with the carried floor beyond chance,
(e_w - e0)^T (Pc + C_w)^-1 (e_w - e0) > `reset_chi2` (the floor changed: a bump's flank, a
ramp's foot): then the floor starts anew from the frame, (e_f, Pf) = (e_w, C_w). The fix's
pose is the tilted fit's conditioned on e = e_f (Gaussian conditioning with the fit's joint
covariance):

    p_f = p_w + C_pe C_ee^-1 (e_f - e_w),    C_f = C_pp - C_pe C_ee^-1 C_ep.           (5)

Where the view does not show the floor (a pair of landmarks, a small cluster that a tilt
does not distinguish from a shift, which the test seldom lets through) the floor is carried,
not re-estimated, and the fix is solved on it (its uncertainty, common to the frames on the
same floor, is not added to each fix's, as the level floor's never was). A flat floor at the
map's height is the prior's mean (s = 0).

What of the calibration's error the carried floor holds is carried beside it (a Schmidt
consider state, Sigma_cal = I in the calibration's standard deviations): s's sensitivity
K = d s / d c, shape (3, Q), predicted as s is (K <- a F K) and taken from the fix's floor
(in the fix's frame B K). A fix's floor is taken only where its change from the carried one
is significant against the pixel noise and the part of the calibration's error the two do
not share (`pose_tilted.floor_change_chi2`): a lens's pseudo-tilt is fixed in the body, so
it is shared by a fix and a floor learnt under a like view and heading, not after a turn.
After the fusion (4) the floor holds

    K_f = Pf (Pc^-1 K_c + C_w^-1 E_w - W^-1 K_c)                                      (6)

(K_c = B K the carried floor's, E_w the fix's floor's), after a reset E_w.

The mounting's own tilt (the camera not quite upright on the body) is no part of this state:
it is fixed in the body, not in the world, and belongs to the calibration
(`CameraModel.T_body_camera`); a turn in place tells the two apart (the floor's tilt turns
with the heading in the body frame, the mount's does not).

Pure: numbers in, numbers out; the state is a small value object.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from localizer.geometry import wrap_angle
from localizer.pose import PoseFix
from localizer.types import FloatArray

FloorPrior = tuple[tuple[float, float, float], FloatArray]  # e = (roll, pitch, dz), cov (3, 3)


@dataclass(frozen=True)
class FloorPlaneConfig:
    """Tuning of the carried floor.

    Attributes:
        enabled: carry the floor and solve every fix's tilt and height with it as the prior
            (False, the default: the old test, a zero-mean tilt taken only when it lowers
            the chi-square enough, the floor at the map's height). Off by default: on level
            floors seen through few landmarks a noisy fit's floor costs accuracy (an
            independent generator's flat hall 1.6 -> 4.6 cm p95, the simulated 50-landmark
            floor's robots about 1.5x), on sloped or uneven floors it pays (the robustness
            matrix's disturbed_real 5.9 -> 3.2 cm, ramp_real 9.8 -> 3.5): turn it on where
            the floor is known not to be level (docs/localizer-models.md, "The floor under
            the robot").
        prior_sigma_m: standard deviation of the floor's height before any fix, metres.
        prior_slope: standard deviation of each slope component before any fix,
            dimensionless (0.005: about 0.3 deg, what a floor's flatness tolerance allows
            over a metre or two).
        change_sigma_m_per_sqrt_m: the height's random walk beyond the plane, metres over
            1 m driven (eq. 3).
        change_slope_per_sqrt_m: the slope's random walk, per component over 1 m driven
            (a ramp's slope changes along it: 0.015 lets the carried slope follow a change
            of a degree over about half a metre of fixes).
        level_length_m: the carried floor returns to the map's level floor over this
            distance driven without a fix that estimates it (eq. 3).
        min_sigma_m, min_slope: the least standard deviations of the prior a fix gets
            (however many fixes were fused: their errors are partly common, the
            calibration's, so they do not average away).
        change_sigma_m, change_slope: the wide prior of a fix that estimates the floor
            (eq. 4; a ramp of a degree or two, a floor some centimetres off the map's
            height), around the carried floor.
        reset_chi2: a fix's floor farther than this (chi-square, 3 dof; 11.34 is its 99 %
            point) from the carried one starts the floor anew instead of being fused.
        calibration_aware: a fix estimates the floor only where its change is significant
            against the pixel noise and the calibration's error too (`solve_pose`'s
            `calibration_jacobian`, `pose_tilted.floor_change_chi2`); False: against the
            pixel noise alone (the chi-square drop).
    """

    enabled: bool = False
    prior_sigma_m: float = 0.03
    prior_slope: float = 0.005
    change_sigma_m_per_sqrt_m: float = 0.003
    change_slope_per_sqrt_m: float = 0.015
    level_length_m: float = 3.0
    min_sigma_m: float = 0.005
    min_slope: float = 0.002
    change_sigma_m: float = 0.05
    change_slope: float = 0.02
    reset_chi2: float = 11.34
    calibration_aware: bool = True


def tilt_map(theta: float) -> FloatArray:
    """M(theta) of eq. (2): the body tilt (roll, pitch) per world gradient (gx, gy)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[-s, c], [-c, -s]])


def state_map(theta: float) -> FloatArray:
    """B(theta): the fix's (roll, pitch, dz) per state (h, gx, gy), to first order."""
    B = np.zeros((3, 3))
    B[:2, 1:] = tilt_map(theta)
    B[2, 0] = 1.0
    return B


def body_tilt(g: FloatArray, theta: float) -> tuple[float, float]:
    """(roll, pitch) of a body at heading `theta` on a floor of world gradient `g`, eq. (1)."""
    c, s = math.cos(theta), math.sin(theta)
    gbx, gby = c * g[0] + s * g[1], -s * g[0] + c * g[1]
    return math.atan(gby), -math.atan(gbx)


def world_gradient(roll: float, pitch: float, theta: float) -> FloatArray:
    """The inverse of `body_tilt`: the world gradient under a body tilted (roll, pitch)."""
    gbx, gby = -math.tan(pitch), math.tan(roll)
    c, s = math.cos(theta), math.sin(theta)
    return np.array([c * gbx - s * gby, s * gbx + c * gby])


@dataclass(frozen=True, eq=False)
class FloorPlane:
    """The carried floor (module docstring).

    Attributes:
        s: (h metres, gx, gy) at `at_xy`, shape (3,).
        covariance: of s, shape (3, 3).
        at_xy: the body position of the last update, metres (None: never updated).
        sensitivity: K = d s / d c, what of the calibration's error s holds per standard
            deviation of each calibration parameter, shape (3, Q) (None: nothing).
    """

    s: FloatArray
    covariance: FloatArray
    at_xy: tuple[float, float] | None = None
    sensitivity: FloatArray | None = None

    @staticmethod
    def level(config: FloorPlaneConfig) -> FloorPlane:
        """A flat floor at the map's height as far as anyone knows: s = 0, the priors."""
        sig = (config.prior_sigma_m, config.prior_slope, config.prior_slope)
        return FloorPlane(np.zeros(3), np.diag(np.square(sig)))

    def predicted(self, x: float, y: float, config: FloorPlaneConfig) -> FloorPlane:
        """The state at (x, y), eq. (3)."""
        if self.at_xy is None:
            return self
        dx, dy = x - self.at_xy[0], y - self.at_xy[1]
        d = math.hypot(dx, dy)
        a = math.exp(-d / config.level_length_m)
        F = np.array([[1.0, dx, dy], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        q = (
            config.change_sigma_m_per_sqrt_m,
            config.change_slope_per_sqrt_m,
            config.change_slope_per_sqrt_m,
        )
        P0 = np.diag(np.square((config.prior_sigma_m, config.prior_slope, config.prior_slope)))
        P = a * a * (F @ self.covariance @ F.T) + (1.0 - a * a) * P0 + d * np.diag(np.square(q))
        K = None if self.sensitivity is None else a * (F @ self.sensitivity)
        return FloorPlane(a * (F @ self.s), P, (x, y), K)

    def prior(self, pose: tuple[float, float, float], config: FloorPlaneConfig) -> FloorPrior:
        """The fix's prior on (roll, pitch, dz) at `pose` (x, y, theta): eq. (1) of the
        predicted state and B P B^T."""
        x, y, theta = pose
        at = self.predicted(x, y, config)
        B = state_map(theta)
        roll, pitch = body_tilt(at.s[1:], theta)
        least = np.square((config.min_sigma_m, config.min_slope, config.min_slope))
        P = at.covariance + np.diag(np.maximum(least - np.diag(at.covariance), 0.0))
        return (roll, pitch, float(at.s[0])), B @ P @ B.T

    def sensitivity_at(
        self, pose: tuple[float, float, float], config: FloorPlaneConfig
    ) -> FloatArray | None:
        """The fix's prior's sensitivity to the calibration at `pose` (x, y, theta): B K of
        the predicted state, shape (3, Q), or None."""
        at = self.predicted(pose[0], pose[1], config)
        return None if at.sensitivity is None else state_map(pose[2]) @ at.sensitivity

    def widened(self, prior: FloorPrior, config: FloorPlaneConfig) -> FloorPrior:
        """The wide prior W of a fix that estimates the floor, around `prior`'s mean:
        B diag(sc_h^2, sc_g^2, sc_g^2) B^T = diag(sc_g^2, sc_g^2, sc_h^2) (`change_*`)."""
        g2, h2 = config.change_slope**2, config.change_sigma_m**2
        return prior[0], np.diag([g2, g2, h2])

    def updated(
        self,
        pose: tuple[float, float, float],
        e: FloatArray,
        e_covariance: FloatArray,
        e_sensitivity: FloatArray | None = None,
    ) -> FloorPlane:
        """The state after a fix at `pose` whose (roll, pitch, dz) posterior (solved with
        `prior` as its prior) is (`e`, `e_covariance`), holding `e_sensitivity` (3, Q) of
        the calibration's error: that posterior in the world frame."""
        x, y, theta = pose
        B = state_map(theta)
        g = world_gradient(float(e[0]), float(e[1]), theta)
        P = B.T @ e_covariance @ B
        K = None if e_sensitivity is None else B.T @ e_sensitivity
        return FloorPlane(np.array([float(e[2]), g[0], g[1]]), 0.5 * (P + P.T), (x, y), K)


def fused(
    carried: FloorPrior, wide: FloorPrior, e_w: FloatArray, C_w: FloatArray, reset_chi2: float
) -> tuple[FloatArray, FloatArray, bool]:
    """The floor (e_f, Pf) after a fix that estimated it with the wide prior `wide` (W,
    around the carried mean) as (e_w, C_w): eq. (4) of the module docstring, or the fix's
    own when it disagrees with the carried (`carried`, (e0, Pc)) beyond `reset_chi2`.
    Returns (e_f, Pf, reset)."""
    e0 = np.asarray(carried[0], dtype=np.float64)
    Pc = np.asarray(carried[1], dtype=np.float64)
    d = e_w - e0
    try:
        if float(d @ np.linalg.solve(Pc + C_w, d)) > reset_chi2:
            return e_w, C_w, True
        info_w, info_W, info_c = np.linalg.inv(C_w), np.linalg.inv(wide[1]), np.linalg.inv(Pc)
        F = info_c + info_w - info_W  # Pc^-1 + I
        Pf = np.linalg.inv(F)
        e_f = Pf @ (info_c @ e0 + info_w @ e_w - info_W @ e0)
    except np.linalg.LinAlgError:
        return e_w, C_w, True
    if not np.all(np.linalg.eigvalsh(0.5 * (Pf + Pf.T)) > 0):
        return e_w, C_w, True
    return e_f, 0.5 * (Pf + Pf.T), False


def conditioned(
    pose: tuple[float, float, float],
    C_pp: FloatArray,
    C_pe: FloatArray,
    C_ee: FloatArray,
    e_w: FloatArray,
    e_f: FloatArray,
) -> tuple[tuple[float, float, float], FloatArray]:
    """A tilted fit's pose (`pose`, joint covariance blocks C_pp, C_pe, C_ee with its floor
    e_w) conditioned on the floor being e_f: eq. (5) of the module docstring."""
    K = C_pe @ np.linalg.inv(C_ee)
    p = np.asarray(pose, dtype=np.float64) + K @ (e_f - e_w)
    C = C_pp - K @ C_pe.T
    return (float(p[0]), float(p[1]), float(p[2])), 0.5 * (C + C.T)


def fused_sensitivity(
    carried: FloorPrior,
    wide: FloorPrior,
    C_w: FloatArray,
    P_f: FloatArray,
    K_c: FloatArray | None,
    E_w: FloatArray | None,
    reset: bool,
) -> FloatArray | None:
    """What of the calibration's error the fused floor holds, eq. (6) of the module
    docstring (the fix's E_w after a reset; None when the fix's is unknown)."""
    if E_w is None:
        return None
    if reset or K_c is None or K_c.shape != E_w.shape:
        return E_w
    info_c = np.linalg.inv(np.asarray(carried[1], dtype=np.float64))
    info_W = np.linalg.inv(np.asarray(wide[1], dtype=np.float64))
    K_f: FloatArray = P_f @ (info_c @ K_c + np.linalg.solve(C_w, E_w) - info_W @ K_c)
    return K_f


def fix_on_floor(
    fix: PoseFix,
    carried: FloorPrior,
    wide: FloorPrior,
    reset_chi2: float,
    carried_sensitivity: FloatArray | None = None,
) -> tuple[PoseFix, tuple[float, float, float]]:
    """A fix solved with the wide prior `wide` around the carried floor `carried`, on the
    floor after it: when it estimated the floor, that floor fused with the carried one (eq.
    4, `fused`) and the pose conditioned on it (eq. 5); else as it is. Also returns what the
    new floor moves a pose on the carried one by, (dx, dy, dtheta) (eq. 5 at e_f minus at
    e0): the earlier fixes, made on the old floor, read on the new one. The fix's
    `floor_sensitivity` becomes the fused floor's (eq. 6, `carried_sensitivity` the carried
    floor's at this pose)."""
    if fix.floor is None or fix.floor_covariance is None or fix.floor_cross is None:
        return fix, (0.0, 0.0, 0.0)
    e_f, P_f, reset = fused(carried, wide, fix.floor, fix.floor_covariance, reset_chi2)
    K_f = fused_sensitivity(
        carried, wide, fix.floor_covariance, P_f, carried_sensitivity, fix.floor_sensitivity, reset
    )
    at = (fix.x, fix.y, fix.theta)
    (x, y, th), C = conditioned(
        at, fix.covariance, fix.floor_cross, fix.floor_covariance, fix.floor, e_f
    )
    (x0, y0, th0), _ = conditioned(
        at,
        fix.covariance,
        fix.floor_cross,
        fix.floor_covariance,
        fix.floor,
        np.asarray(carried[0], dtype=np.float64),
    )
    out = dataclasses.replace(
        fix,
        x=x,
        y=y,
        theta=float(wrap_angle(th)),
        covariance=C,
        tilt=e_f[:2].copy(),
        floor=e_f,
        floor_covariance=P_f,
        floor_sensitivity=K_f,
    )
    return out, (x - x0, y - y0, float(wrap_angle(th - th0)))
