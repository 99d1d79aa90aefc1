"""The survey solved as the drive goes, each update at a cost that does not grow with the
drive: a fixed-lag smoother over the survey's bundle adjustment (docs/survey.md).

The first update solves the drive from its start (as `survey.bundle.solve_survey` does) once
both anchors are identified. After each update the keyframes older than `lag_s` before the
drive's latest are marginalised (`survey.marginal.marginalise`): what their spots and wheels
said of the kept keyframe, every landmark, the wheels and the camera becomes a Gaussian
prior, and the next update solves only the frames from that keyframe on with it. Spots are
named in each window as in the whole-drive solve (blinks first, then map-consistent
association against the landmarks placed so far); each landmark's evidence (views,
residuals) is carried across windows (`survey.tally`). The state is plain data
(`IncrementalSurvey`), so a server can keep it across a restart
(`survey.incremental_file`).

Per update the work is one window (`lag_s` plus the new frames) and the landmarks' dense
block (three unknowns a landmark): a 15-minute drive costs what a one-minute one does.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from localizer.types import FloatArray, IntArray
from survey.association import unnamed_reasons
from survey.bundle import FitSolution, solve_fit
from survey.drive import SurveyDrive, survey_problem
from survey.estimates import survey_result
from survey.marginal import WindowPrior, marginalise
from survey.problem import BundleConfig, SurveyProblem
from survey.result import SurveyResult
from survey.tally import Tally, tallies

NS = 1_000_000_000


@dataclass(frozen=True)
class IncrementalConfig:
    """Tuning of the incremental survey.

    Attributes:
        lag_s: keyframes this much older than the drive's latest are marginalised; the
            frames after stay in the next window (their spots named again with what came
            since), seconds.
        min_window_s: an update with less new drive than this since the window began waits
            (returns the state as it was), seconds.
    """

    lag_s: float = 10.0
    min_window_s: float = 1.0


@dataclass(frozen=True, eq=False)
class IncrementalSurvey:
    """Where an incremental survey is: plain data, nothing running.

    Attributes:
        prior: what the marginalised part of the drive says (None before the first
            marginalisation: the next update solves from the drive's start).
        trajectory_t_ns, trajectory: the marginalised keyframes' times and poses.
        carried: each landmark's evidence from the marginalised keyframes.
        result: the latest estimate (None before the first).
        updates: updates solved so far.
    """

    prior: WindowPrior | None = None
    trajectory_t_ns: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    trajectory: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    carried: dict[int, Tally] = field(default_factory=dict)
    result: SurveyResult | None = None
    updates: int = 0

    @property
    def window_start_ns(self) -> int | None:
        """The first frame the next update needs (None: the drive's first)."""
        return None if self.prior is None else self.prior.t_ns

    def restarted(self) -> IncrementalSurvey:
        """The state for a drive that goes on after a break in the wheels' record (a server
        restart): the kept pose is marginalised too, so the next window starts from the
        landmarks it sees, not from where the robot was."""
        if self.prior is None:
            return self
        return dataclasses.replace(self, prior=self.prior.without_pose(-1))


def _scaled(cfg: BundleConfig, prior: WindowPrior | None) -> BundleConfig:
    """The tuning with the spots' and the wheels' sigmas as the residuals showed them."""
    if prior is None:
        return cfg
    s, o = prior.pixel_scale, prior.odometry_scale
    return dataclasses.replace(
        cfg,
        pixel_sigma_px=cfg.pixel_sigma_px * s,
        odom_sigma_m_per_sqrt_m=cfg.odom_sigma_m_per_sqrt_m * o,
        odom_sigma_floor_m=cfg.odom_sigma_floor_m * o,
        odom_heading_sigma_rad_per_sqrt_m=cfg.odom_heading_sigma_rad_per_sqrt_m * o,
        odom_heading_sigma_rad_per_sqrt_rad=cfg.odom_heading_sigma_rad_per_sqrt_rad * o,
        odom_heading_floor_rad=cfg.odom_heading_floor_rad * o,
    )


def update(
    state: IncrementalSurvey,
    drive: SurveyDrive,
    anchors: list[int],
    config: BundleConfig,
    inc: IncrementalConfig | None = None,
) -> IncrementalSurvey:
    """Solve the window `drive` (its frames from `state.window_start_ns` on, the LED states
    in force from before its first frame) and return the new state.

    Raises:
        ValueError: as `survey.bundle.solve_survey` (an anchor not identified yet: the
            first update), or a drive that does not begin at the window's keyframe.
    """
    inc = inc or IncrementalConfig()
    prior = state.prior
    if len(drive.frame_t_ns) < 2:
        return state
    start = state.window_start_ns
    if start is not None and start >= 0 and int(drive.frame_t_ns[0]) != start:
        raise ValueError("survey: the window's drive must begin at the kept keyframe")
    span_s = (int(drive.frame_t_ns[-1]) - int(drive.frame_t_ns[0])) / NS
    if prior is not None and span_s < inc.min_window_s:
        return state
    if prior is not None and prior.t_ns < 0:  # after a break: the window starts where it is
        prior = dataclasses.replace(prior, t_ns=int(drive.frame_t_ns[0]))
        state = dataclasses.replace(state, prior=prior)
    cfg = _scaled(config, prior)
    problem = survey_problem(drive, anchors)
    sol = solve_fit(problem, cfg, prior=prior)
    result = _result(problem, cfg, sol, state.carried, state)
    fit = sol.fit
    newest = int(fit.key_t[-1])
    old = np.flatnonzero(fit.key_t <= newest - round(inc.lag_s * NS))
    j = int(old[-1]) if len(old) else 0
    if j < 1:  # the window is shorter than the lag: it grows until the next update
        return dataclasses.replace(state, prior=prior, result=result, updates=state.updates + 1)
    new_prior = marginalise(fit, cfg.huber_scale, j, prior)
    frame_j = int(np.searchsorted(problem.frame_t_ns, fit.key_t[j]))
    done = tallies(
        problem.observations,
        fit,
        sol.labels,
        sol.rejected,
        cfg.independent_view_m,
        keys_before=j,
        frames_before=frame_j,
    )
    carried = dict(state.carried)
    for lid, t in done.items():
        carried[lid] = carried[lid].plus(t, cfg.independent_view_m) if lid in carried else t
    poses = fit.poses()
    return IncrementalSurvey(
        new_prior,
        np.concatenate([state.trajectory_t_ns, fit.key_t[:j]]).astype(np.int64),
        np.concatenate([state.trajectory, poses[:j]]),
        carried,
        result,
        state.updates + 1,
    )


def _result(
    problem: SurveyProblem,
    cfg: BundleConfig,
    sol: FitSolution,
    carried: dict[int, Tally],
    state: IncrementalSurvey,
) -> SurveyResult:
    result = survey_result(
        problem, cfg, sol.anchors, sol.fit, sol.labels, sol.rejected, carried=carried
    )
    why = unnamed_reasons(problem, cfg, sol.fit, sol.labels, set(result.landmarks), sol.doubt)
    return dataclasses.replace(
        result,
        unnamed=why,
        trajectory_t_ns=np.concatenate([state.trajectory_t_ns, result.trajectory_t_ns]),
        trajectory=np.concatenate([state.trajectory, result.trajectory]),
    )


def window_of(drive: SurveyDrive, start_ns: int | None) -> SurveyDrive:
    """The part of `drive` an update needs: its frames and wheels from `start_ns` on (all
    when None), and the LED states from the last change before it."""
    if start_ns is None or start_ns < 0:
        return drive
    f = int(np.searchsorted(drive.frame_t_ns, start_ns))
    o = max(int(np.searchsorted(drive.odom_t_ns, start_ns)) - 1, 0)
    before = [i for i, c in enumerate(drive.leds) if c.t_ns <= start_ns]
    first_led = before[-1] if before else 0
    return dataclasses.replace(
        drive,
        frame_t_ns=drive.frame_t_ns[f:],
        frame_spots=drive.frame_spots[f:],
        odom_t_ns=drive.odom_t_ns[o:],
        odom_v=drive.odom_v[o:],
        leds=drive.leds[first_led:],
    )
