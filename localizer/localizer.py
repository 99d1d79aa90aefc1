"""The localizer: a sans-I/O state machine from IR frames, odometry and LED states to poses.

Feed it events in time order with `handle(event)`; it returns outputs: for every frame exactly
one `PoseEstimate` (or `NoPose` before the first fix), plus `LedRequest`s when it wants LEDs
changed (the owner may ignore them, as a replay does).

Pipeline per frame (docs/localizer.md):
1. odometry up to the frame's time goes through `PoseFilter.predict` (Sec. IV-B, eqs. 5-6);
2. identifying (no pose yet, or lost): full-frame spots to the `Identifier` (Sec. III-A);
   two identified landmarks, carried to the frame's time by odometry, give the first fix;
3. tracking: eq. (3) predicts the lit landmarks' pixels, spots are searched in windows sized
   from speed, frame interval, scale, radius and uncertainty (Sec. IV-A.1), and assigned by the
   bottleneck rule; new landmarks are handed off by gated prediction (eq. 4) and, after long
   dead reckoning, only through a hypothesis that agrees with the map's geometry;
4. `solve_pose` over every matched landmark (tilt too with 3+), gated by the residual and the
   normalised innovation, fused by `PoseFilter.update_fix`.
Modes: identifying -> landmark <-> dead_reckoning; lost when the uncertainty grows past a
bound or the observations keep disagreeing with the map (then it re-identifies).

`Localizer` coordinates; the state lives in objects named for what they hold: the LEDs
(`led_knowledge`), odometry and the motion model (`dead_reckoning`), identification by
blinking (`blink_identification`) or by geometry (`passive_identification`), tracking
(`landmark_tracker`), getting lost and re-localizing (`recovery`), the online
self-calibration (`calibration_feed`) and the frame's output (`frame_report`).
"""

from __future__ import annotations

import math

import numpy as np

from localizer.after_frame import AfterFrame
from localizer.blink_identification import BlinkIdentification
from localizer.calibration_feed import feed_self_calibration
from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.constellation import ConstellationMatch
from localizer.dead_reckoning import DeadReckoning
from localizer.events import (
    Event,
    FrameObserved,
    ImuMeasured,
    LedsChanged,
    Mode,
    NoPose,
    OdometryMeasured,
    Output,
    PoseEstimate,
    RelocalizeRequested,
    SpotsObserved,
)
from localizer.frame_report import FrameTiming, frame_facts, frame_output
from localizer.landmark_liveness import LandmarkLiveness
from localizer.landmark_map import LandmarkMap
from localizer.landmark_tracker import LandmarkTracker
from localizer.led_knowledge import LedKnowledge
from localizer.online_calibration import OnlineCalibration
from localizer.passive_identification import PassiveIdentifier, passive_settings
from localizer.pose import PoseFix
from localizer.pose_filter import PoseFilter
from localizer.recovery import Recovery
from localizer.robot import RobotGeometry
from localizer.spots import Spots
from localizer.types import FloatArray

_NS = 1e-9
_CHI2_2DOF_95_RADIUS = 2.4477  # sqrt of chi-square's 95 % point with 2 dof: radius / sigma


class Localizer:
    """IR landmark localizer (the paper's method, with EKF fusion of odometry and fixes).

    Args:
        camera: lens and mounting of the upward camera.
        landmark_map: landmark IDs and LED positions.
        robot: wheel geometry (wheel base, maximum speed).
        config: tuning; defaults to `LocalizerConfig()`.
    """

    def __init__(
        self,
        camera: CameraModel,
        landmark_map: LandmarkMap,
        robot: RobotGeometry,
        config: LocalizerConfig | None = None,
    ) -> None:
        self.camera = camera
        self.robot = robot
        # (passive lights larger than LED spots widen the detector and the windows)
        self.config = passive_settings(config or LocalizerConfig(), camera, landmark_map)
        self._filter: PoseFilter | None = None
        self._mode: Mode = "identifying"
        self._latest: PoseEstimate | None = None
        self._leds = LedKnowledge(landmark_map)  # lit, being switched, asked for, since when
        self._t_filter = 0  # time of the filter's state (the last sample or fused frame)
        self._commit = False  # this frame's filter is kept (a fix, a reset)
        self._timing = FrameTiming()  # the interval between frames and the usual one
        self._expected: tuple[int, ...] = ()  # lit landmarks predicted in view, this frame
        self._tracker = LandmarkTracker(camera, robot, self.config, landmark_map)
        # rejections, where it got lost, re-localization, landmark liveness, runs of fixes
        self._recovery = Recovery(
            self.config,
            len(landmark_map.ids),
            max_speed_m_s=robot.max_speed,
            max_turn_rad_s=self._tracker.max_angular_speed_rad_s,
            spacing_m=self._tracker.spacing_m,
        )
        self._passive = PassiveIdentifier(
            self.config.passive, self.config.constellation, self.config.relocalization
        )
        # odometry, or without it the motion model; the body's tilt from an IMU
        self._reckoning = DeadReckoning(self.config, robot, self._tracker.max_angular_speed_rad_s)
        self._odometry = self._reckoning.odometry  # the raw track (the same object)
        # the identifier, the candidates' order by view, the first fix
        self._blink = BlinkIdentification(self.config, self._odometry, robot.wheel_base)
        self._reseeded = False  # this frame's filter was re-seeded from a run of fixes
        # what explains a frame without a fix (`pose_quality.FrameFacts`)
        self._facts: dict[str, bool | int | float] = {}
        sc = self.config.self_calibration
        self.calibration = OnlineCalibration(camera, sc) if sc.enabled else None
        self._after = AfterFrame()  # a fused frame's learning, done after its pose is out
        self.set_map(landmark_map)

    # -- public API ----------------------------------------------------------------------------
    @property
    def mode(self) -> Mode:
        """The current mode."""
        return self._mode

    @property
    def liveness(self) -> LandmarkLiveness:
        """What tracking learnt of each landmark (lit, dark), per map row."""
        return self._recovery.liveness

    @property
    def latest(self) -> PoseEstimate | None:
        """The last pose estimate output, if any."""
        return self._latest

    @property
    def passive_status(self) -> ConstellationMatch | None:
        """Passive lights: the last decision of the identification by geometry and its
        reason ("ambiguous: ... a regular layout"); None when none was made (or the map's
        landmarks blink)."""
        return self._passive.status if self._passive.active else None

    def set_map(self, landmark_map: LandmarkMap) -> None:
        """Use a new map. The pose is kept and tracking goes on with the new map (if the
        observations disagree with it the localizer gets lost and re-identifies); without a
        pose, identification starts over."""
        self._after.run()
        self.map = landmark_map
        self._leds.set_map(landmark_map)
        self._tracker.set_map(landmark_map)
        # nothing learnt of the new landmarks (lit, dark), no run of fixes
        self._recovery.set_map(len(landmark_map.ids), self._tracker.spacing_m)
        self._half_diag = math.hypot(self.camera.width, self.camera.height) / 2
        self._blink.set_map(landmark_map, self.camera, self._motion_bound_px)
        self._passive.set_map(landmark_map)
        self._start_identification()
        if self._filter is not None and self._mode != "lost":
            self._leds.sweeping = False  # keep tracking with the new map; lost if it disagrees

    def set_initial_pose(
        self,
        x: float,
        y: float,
        theta: float,
        t_ns: int,
        *,
        radius_m: float | None = None,
        sigma_rad: float | None = None,
    ) -> None:
        """A prior pose (e.g. from the operator): outputs poses and guides identification.

        Args:
            radius_m: the robot is within this of (x, y) with 95 % probability (position
                sigma radius / 2.45, the chi-square 2-dof 95 % point); None:
                `FusionConfig.initial_sigma_m`.
            sigma_rad: heading standard deviation; None: `FusionConfig.initial_sigma_rad`.
        """
        self._after.run()
        f = self.config.fusion
        for name, v in (("x", x), ("y", y), ("theta", theta)):
            if not math.isfinite(v):
                raise ValueError(f"set_initial_pose: {name} must be finite, got {v!r}")
        if radius_m is not None and not (math.isfinite(radius_m) and radius_m > 0):
            raise ValueError(f"set_initial_pose: radius_m must be > 0 metres, got {radius_m!r}")
        s = f.initial_sigma_m if radius_m is None else radius_m / _CHI2_2DOF_95_RADIUS
        s_th = f.initial_sigma_rad if sigma_rad is None else sigma_rad
        cov = np.diag([s * s, s * s, s_th * s_th])
        self._reset_filter(x, y, theta, cov, t_ns)
        self._start_identification()

    def skip_frame(self, t_ns: int) -> PoseEstimate | NoPose:
        """A frame that could not be read: the pose at `t_ns` from odometry alone."""
        self._after.run()
        base = self._advance(t_ns)
        self._expected = ()
        if self._filter is not None and self._mode == "landmark":
            self._mode = "dead_reckoning"
        self._facts = {"skipped": True}
        out = self._output(t_ns, ())
        self._settle(t_ns, base)
        return out

    def handle(self, event: Event) -> list[Output]:
        """Process one event; returns the outputs (see the module docstring)."""
        self._after.run()
        if isinstance(event, OdometryMeasured):
            self._on_odometry(event)
            return []
        if isinstance(event, LedsChanged):
            self._leds.reported(event)
            self._blink.identifier.led_confirmed(event.t_ns, self._leds.known_lit())
            return self._requests(event.t_ns)
        if isinstance(event, RelocalizeRequested):
            self._filter = None
            self._t_filter = event.t_ns
            self._mode = "identifying"
            if event.near is not None:
                self.set_initial_pose(*event.near, event.t_ns, radius_m=event.radius_m)
            else:
                self._start_identification()
            return self._requests(event.t_ns)
        if isinstance(event, ImuMeasured):
            self._reckoning.imu(event)
            return []
        if isinstance(event, FrameObserved | SpotsObserved):
            out: list[Output] = [self._on_frame(event)]
            return out + self._requests(event.t_ns)
        raise TypeError(f"Localizer.handle: unknown event {type(event).__name__}")

    # -- odometry and the filter ---------------------------------------------------------------
    def _reset_filter(self, x: float, y: float, theta: float, cov: FloatArray, t_ns: int) -> None:
        if self._filter is None:
            self._filter = PoseFilter(
                x, y, theta, cov, wheel_base=self.robot.wheel_base, config=self.config.filter
            )
        else:
            self._filter.reset(x, y, theta, cov)
        t_state = self._odometry.t_state_ns
        self._odometry.t_state_ns = t_ns if t_state is None else max(t_state, t_ns)
        self._t_filter = max(self._t_filter, t_ns)
        self._commit = True
        self._recovery.reset(t_ns)
        if self.calibration is not None:
            self.calibration.break_track()
        self._tracker.last_matched = frozenset()
        self._reckoning.motion.break_track()

    def _advance(self, t_ns: int) -> PoseFilter | None:
        """Extrapolate odometry (raw, and a copy of the filter) from the last state time to
        `t_ns` (`DeadReckoning.extrapolate`); returns the committed filter (None: none),
        which stays as it was: the frame works on the copy (`self._filter`), kept only on
        `_settle`."""
        base = self._filter
        work = self._reckoning.extrapolate(t_ns, base, self._t_filter)
        if work is not None:
            self._filter = work
        return base

    def _settle(self, t_ns: int, base: PoseFilter | None) -> None:
        """End of a frame: keep its filter when it took a fix (or was reset, or odometry is
        stale), else go back to the committed one: the next odometry sample says what the
        wheels did since the last one, better than the extrapolation."""
        keep = self._commit or base is None or not self._reckoning.fresh(t_ns)
        self._commit = False
        if keep:
            self._t_filter = max(self._t_filter, t_ns)
        else:
            self._filter = base

    def _on_odometry(self, e: OdometryMeasured) -> None:
        vl, vr, step_s = self._odometry.add_sample(e.t_ns, e.v_left, e.v_right)
        self._recovery.travel_m += 0.5 * (abs(vl) + abs(vr)) * step_s
        dt = (e.t_ns - self._t_filter) * _NS
        if self._filter is not None and dt > 0:
            self._filter.predict(vl, vr, dt)
        self._t_filter = max(self._t_filter, e.t_ns)

    def _motion_bound_px(self, t0_ns: int, t1_ns: int) -> float:
        """Bound on a spot's image motion between two times (`DeadReckoning`), pixels."""
        scale = self._tracker.scale_px_per_m
        return self._reckoning.motion_bound_px(t0_ns, t1_ns, scale, self._half_diag)

    # -- frames --------------------------------------------------------------------------------
    def _on_frame(self, e: FrameObserved | SpotsObserved) -> PoseEstimate | NoPose:
        t = e.t_ns
        base = self._advance(t)
        dt_frame, self._facts = self._timing.frame(t)
        self._odometry.mark(t)
        used: tuple[int, ...] = ()
        self._expected = ()
        if self._filter is None or self._mode in ("identifying", "lost"):
            spots = self._tracker.full_spots(e)
            if self._passive.active:  # lights that cannot blink: by geometry
                prior = (
                    None if self._filter is None else (self._filter.pose, self._filter.covariance)
                )
                odo = self._odometry.pose
                fix = self._passive.fix(t, self.camera, spots, self._tracker.noise, odo, prior)
            else:
                lit = self._leds.lit_for_evidence(t, self.config.identification)
                self._blink.identifier.observe(t, lit, spots.pixels, spots.intensities)
                fix = self._blink.first_fix(t, self.camera)
            if fix is not None:
                self._reset_filter(fix.x, fix.y, fix.theta, fix.covariance, t)
                self._mode = "landmark"
                used = fix.landmark_ids
            elif self._filter is not None and not self._passive.active:
                # With a prior (lost, or an initial pose) also try a map-consistent hand-off.
                used = self._track(e, dt_frame, spots=spots, reacquire=True)
                if not used:
                    used = self._relocalize(t, spots)
                if used:
                    self._mode = "landmark"
                    self._leds.sweeping = False
                    self._leds.want_all = True
        else:
            self._recovery.widen_unexplained(self._filter, t, self._tracker.spacing_m)
            used = self._track(e, dt_frame)
            self._mode = "landmark" if used else "dead_reckoning"
            if used:
                self._recovery.learn_liveness(
                    t,
                    self.camera,
                    self.map,
                    self._expected,
                    self._tracker,
                    self._filter,
                    self._after,
                )
            if used and self.calibration is not None and not self._reseeded:
                self._self_calibrate(t)
        self._commit = self._commit or bool(used)
        if used:
            fused = self._tracker.last_fused
            fix = None if fused is None else fused[2]
            self._reckoning.fixed(t, used, fix, self._filter, self._after)
        self._check_lost(t)
        out = self._output(t, used)
        self._settle(t, base)
        return out

    def _track(
        self,
        e: FrameObserved | SpotsObserved,
        dt_frame: float,
        *,
        spots: Spots | None = None,
        reacquire: bool = False,
    ) -> tuple[int, ...]:
        """A tracking step (`LandmarkTracker.step`); returns the IDs fused."""
        if self._filter is None:
            return ()
        leds = self._leds
        cand = None if leds.lit is None and not leds.changing else leds.lit_rows()
        reckoning = self._reckoning
        fresh = reckoning.fresh(e.t_ns)
        since = reckoning.since_sample_s(e.t_ns, fresh)
        self._tracker.imu_tilt = reckoning.tilt_at(e.t_ns)
        unpredicted = reckoning.unpredicted_bounds(e.t_ns)
        result = self._tracker.step(
            self._filter,
            e,
            dt_frame_s=dt_frame,
            fresh_odometry=fresh,
            unpredicted_bounds=unpredicted,
            since_sample_s=since,
            travel_since_fix_m=self._recovery.travel_m,
            candidates=cand,
            spots=spots,
            reacquire=reacquire,
        )
        self._expected = result.expected
        self._reseeded = False
        self._facts["unexplained"] = result.unexplained
        self._facts["rejected_fix"] = result.rejected is not None
        if result.used:
            f = self._filter
            self._recovery.fix_run.fused(e.t_ns, f.pose, f.covariance, result.used)
        elif not reacquire and result.rejected is not None:
            result = result._replace(used=self._reseed(e.t_ns, result.rejected))
        self._recovery.tracked(e.t_ns, result.used, result.unexplained)
        return result.used

    def _reseed(self, t_ns: int, fix: PoseFix) -> tuple[int, ...]:
        """A good fix the filter rejected: when it completes (or continues) a run of such
        fixes that form one track the robot could have driven by itself (`fix_run`: the
        odometry is what is wrong, a stall, a spinning wheel, a bump), the filter is re-seeded
        at it (`Recovery.reseed`); returns its IDs (empty: not taken). The odometry's track
        is broken there, so the self-calibration starts a new one."""
        if self._filter is None:
            return ()
        used = self._recovery.reseed(t_ns, fix, self._tracker, self._filter)
        if used:
            self._reseeded = True
            if self.calibration is not None:
                self.calibration.break_track()
        return used

    def _relocalize(self, t_ns: int, spots: Spots) -> tuple[int, ...]:
        """Re-localization without LEDs (`Recovery.relocalize`); returns the IDs of the fix
        the filter was reset at (empty: none)."""
        if self._filter is None or self._leds.changing:
            return ()
        cand = None if self._leds.lit is None else self._leds.lit_rows()
        fix = self._recovery.relocalize(
            self._tracker,
            self._filter,
            spots,
            cand,
            mode=self._mode,
            t_ns=t_ns,
            odometry=self._odometry,
        )
        if fix is None:
            return ()
        self._reset_filter(fix.x, fix.y, fix.theta, fix.covariance, t_ns)
        return fix.landmark_ids

    def _self_calibrate(self, t_ns: int) -> None:
        """Feed the fused fix to the online self-calibration (`feed_self_calibration`)
        after the frame's pose is out (`AfterFrame`); when it hands back a corrected camera,
        use it from then on (the pose moved to where the frame's spots put it through the
        corrected lens)."""
        fused = self._tracker.last_fused
        if self.calibration is None or self._filter is None or fused is None:
            return
        calibration, odometry = self.calibration, self._odometry.pose_at(t_ns)

        def learn() -> None:
            if self._filter is None:
                return
            noise = self._tracker.noise
            camera = feed_self_calibration(
                calibration, t_ns, fused, noise, self._filter, self.map, odometry
            )
            if camera is None:
                return
            self.camera = camera
            self._tracker.camera = camera
            self._tracker.set_map(self.map)  # scale, reach and the noise model of the new lens

        self._after.defer(learn)

    # -- modes and outputs ---------------------------------------------------------------------
    def _check_lost(self, t_ns: int) -> None:
        """Lost when the uncertainty grew past its bound or the spots kept disagreeing
        (`Recovery.lost_sigma`): identification starts over (around the pose)."""
        if self._filter is None or self._mode in ("identifying", "lost"):
            return
        sigma = self._recovery.lost_sigma(self._filter)
        if sigma is None:
            return
        self._mode = "lost"
        if self.calibration is not None:
            self.calibration.break_track()
        self._start_identification()
        self._commit = True
        self._recovery.lose(self._filter, sigma, self._odometry.pose)

    def _start_identification(self) -> None:
        f = self._filter
        self._blink.restart(None if f is None else (float(f.state[0]), float(f.state[1])))
        self._leds.restart_sweep(not self._passive.active)  # passive lights are never switched

    def _requests(self, t_ns: int) -> list[Output]:
        """LED requests of an identification in progress (`BlinkIdentification.requests`)."""
        return list(self._blink.requests(t_ns, self._leds, self.camera, self._timing.interval_s))

    def _output(self, t_ns: int, used: tuple[int, ...]) -> PoseEstimate | NoPose:
        """The frame's output (`frame_report`); remembered as `latest` when a pose."""
        f = self._filter
        pose = None if f is None else f.output_pose
        facts = frame_facts(
            t_ns,
            pose,
            used,
            mode=self._mode,
            notes=self._facts,
            recovery=self._recovery,
            leds=self._leds,
            camera=self.camera,
            landmark_map=self.map,
            t_odometry_ns=self._odometry.t_sample_ns,
            config=self.config,
        )
        out = frame_output(
            t_ns, f, pose, self._mode, used, self._expected, facts, self.config.quality
        )
        if isinstance(out, PoseEstimate):
            self._latest = out
        return out
