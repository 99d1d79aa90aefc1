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
"""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel
from localizer.candidate_order import ViewOrdering, order_by_view
from localizer.config import LocalizerConfig
from localizer.constellation import ConstellationMatch
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
from localizer.first_fix import first_fix
from localizer.fix_run import FixRun
from localizer.geometry import wrap_angle
from localizer.handoff import position_sigma_m, visible_radius_m
from localizer.hypothesis_set import HypothesisSet
from localizer.identification import Identifier
from localizer.imu_tilt import GravityTilt
from localizer.landmark_liveness import LandmarkLiveness
from localizer.landmark_map import LandmarkMap
from localizer.landmark_tracker import LandmarkTracker
from localizer.led_knowledge import LedKnowledge
from localizer.motion_model import ConstantVelocity
from localizer.odometry import integrate_arc
from localizer.odometry_track import OdometryTrack
from localizer.online_calibration import OnlineCalibration
from localizer.passive_identification import PassiveIdentifier, fix_from_pairs, passive_settings
from localizer.pose import PoseFix, solve_pose
from localizer.pose_filter import PoseFilter
from localizer.pose_quality import (
    FrameFacts,
    deviation_radius_m,
    landmarks_in_view,
    published_covariance,
    quality_from_deviation,
    reason_for,
    reason_text,
)
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
        self._odometry = OdometryTrack(
            self.robot.wheel_base,
            self.config.fusion.odometry_history_s,
            interval_mean=self.config.fusion.odometry_interval_mean,
        )
        self._t_filter = 0  # time of the filter's state (the last sample or fused frame)
        self._commit = False  # this frame's filter is kept (a fix, a reset)
        self._t_relocalized: int | None = None  # the last re-localization attempt
        self._hypotheses = HypothesisSet(self.config.relocalization)  # kept alive while lost
        # where it got lost: pose, position sigma (m), heading variance, raw odometry pose
        self._lost_at: tuple[float, float, float, float, float, tuple[float, float, float]] = (
            0.0, 0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0)
        )  # fmt: skip
        self._t_frame: int | None = None
        self._expected: tuple[int, ...] = ()  # lit landmarks predicted in view, this frame
        self._rejections = 0  # frames in a row whose spots no fused fix explained
        self._travel_m = 0.0  # odometry travel since the last fused fix (the slip hypothesis)
        self._t_explained = 0  # the last frame whose spots a fix explained (or none predicted)
        # the sighting the candidates were last ordered from, and the raw odometry then
        ic = self.config.identification
        self._view = ViewOrdering(ic.reorder_distance_m, ic.reorder_turn_rad)
        self._frame_interval_s: float | None = None  # between the last two frames
        self._tracker = LandmarkTracker(camera, robot, self.config, landmark_map)
        self._passive = PassiveIdentifier(
            self.config.passive, self.config.constellation, self.config.relocalization
        )
        # speed and turn rate for frames without odometry (constant velocity and turn)
        self._motion = ConstantVelocity(
            self.config.motion,
            max_speed_m_s=robot.max_speed,
            max_turn_rad_s=self._tracker.max_angular_speed_rad_s,
        )
        self._gravity = GravityTilt(self.config.imu)  # the body's tilt from an IMU
        self._reseeded = False  # this frame's filter was re-seeded from a run of fixes
        # what explains a frame without a fix (`pose_quality.FrameFacts`)
        self._facts: dict[str, bool | int | float] = {}
        self._typical_gap_s = 0.0  # the usual frame interval (smoothed)
        self._lost_by_disagreement = False  # lost: the spots disagreed (not sigma's growth)
        sc = self.config.self_calibration
        self.calibration = OnlineCalibration(camera, sc) if sc.enabled else None
        self.set_map(landmark_map)

    # -- public API ----------------------------------------------------------------------------
    @property
    def mode(self) -> Mode:
        """The current mode."""
        return self._mode

    @property
    def liveness(self) -> LandmarkLiveness:
        """What tracking learnt of each landmark (lit, dark), per map row."""
        return self._liveness

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
        self.map = landmark_map
        self._leds.set_map(landmark_map)
        self._tracker.set_map(landmark_map)
        # fixes the odometry disagrees with, and the last fused one they must link to
        self._fix_run = FixRun(
            self.config.fix_run,
            max_speed_m_s=self.robot.max_speed,
            max_turn_rad_s=self._tracker.max_angular_speed_rad_s,
            spacing_m=self._tracker.spacing_m,
        )
        # what tracking learnt of each landmark (lit, dark): what its absence weighs
        self._liveness = LandmarkLiveness(len(landmark_map.ids), self.config.relocalization)
        self._t_liveness: int | None = None
        self._half_diag = math.hypot(self.camera.width, self.camera.height) / 2
        self._identifier = Identifier(
            self.config.identification,
            landmark_map.ids.tolist(),
            positions=landmark_map.positions,
            image_size=(self.camera.width, self.camera.height),
            principal_point=(self.camera.cu, self.camera.cv),
            motion_px=self._motion_bound_px,
            odometry_at=self._odometry.pose_at,
        )
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
        base = self._advance(t_ns, *self._odometry.speeds)
        self._expected = ()
        if self._filter is not None and self._mode == "landmark":
            self._mode = "dead_reckoning"
        self._facts = {"skipped": True}
        out = self._output(t_ns, ())
        self._settle(t_ns, base)
        return out

    def handle(self, event: Event) -> list[Output]:
        """Process one event; returns the outputs (see the module docstring)."""
        if isinstance(event, OdometryMeasured):
            self._on_odometry(event)
            return []
        if isinstance(event, LedsChanged):
            self._leds.reported(event)
            self._identifier.led_confirmed(event.t_ns, self._leds.known_lit())
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
            self._on_imu(event)
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
        self._rejections = 0
        self._travel_m = 0.0
        self._t_explained = t_ns
        if self.calibration is not None:
            self.calibration.break_track()
        self._hypotheses.clear()
        self._tracker.last_matched = frozenset()
        self._fix_run.clear()
        self._motion.break_track()

    def _advance(self, t_ns: int, v_left: float, v_right: float) -> PoseFilter | None:
        """Extrapolate odometry (raw, and a copy of the filter) from the last state time to
        `t_ns` at the given speeds; returns the committed filter (None: none), which stays
        as it was: the frame works on the copy (`self._filter`), kept only on `_settle`.
        Without odometry (`_model_drives`) the motion model's speed and turn rate drive
        both instead, with its process noise."""
        model = self._model_drives(t_ns)
        if model:
            self._motion.predict(t_ns)
            v_left, v_right = self._motion.wheel_speeds(self.robot.wheel_base)
        self._odometry.step(t_ns, v_left, v_right)
        base = self._filter
        if base is None:
            return None
        work = base.copy()
        dt = (t_ns - self._t_filter) * _NS
        if dt > 0 and model:
            q = self._motion.process_noise(dt)
            work.predict_motion(self._motion.v, self._motion.w, dt, q.var_xy_m2, q.var_theta_rad2)
        elif dt > 0:
            work.predict(v_left, v_right, dt)
        self._filter = work
        return base

    def _model_drives(self, t_ns: int) -> bool:
        """Whether the motion model predicts instead of the odometry: it is on and no
        odometry sample arrived within `MotionModelConfig.silent_odometry_s` (or ever)."""
        mc = self.config.motion
        t_sample = self._odometry.t_sample_ns
        return mc.enabled and (t_sample is None or (t_ns - t_sample) * _NS > mc.silent_odometry_s)

    def _motion_fixed(self, t_ns: int, used: tuple[int, ...]) -> None:
        """A frame fused a fix: the motion model measures the speed and turn rate from it
        and the one before (the fix's own pose and covariance; after a reset, the filter's,
        which is the fix's)."""
        fused = self._tracker.last_fused
        if fused is not None and tuple(fused[2].landmark_ids) == tuple(used):
            fix = fused[2]
            x, y, th, cov = fix.x, fix.y, fix.theta, fix.covariance
        elif self._filter is not None:
            x, y, th = self._filter.pose
            cov = self._filter.covariance
        else:
            return
        var_xy = 0.5 * float(cov[0, 0] + cov[1, 1])
        self._motion.fixed(t_ns, x, y, th, var_xy, float(cov[2, 2]))
        if self._model_drives(t_ns) and self.config.motion.snap_output and self._filter is not None:
            # without odometry a fix's correction is mostly motion the model did not
            # foresee (a turn begun or ended): smoothing it would only make a lag
            self._filter.snap_output()

    def _settle(self, t_ns: int, base: PoseFilter | None) -> None:
        """End of a frame: keep its filter when it took a fix (or was reset, or odometry is
        stale), else go back to the committed one: the next odometry sample says what the
        wheels did since the last one, better than the extrapolation."""
        keep = self._commit or base is None or not self._fresh_odometry(t_ns)
        self._commit = False
        if keep:
            self._t_filter = max(self._t_filter, t_ns)
        else:
            self._filter = base

    def _fresh_odometry(self, t_ns: int) -> bool:
        t_sample = self._odometry.t_sample_ns
        return (
            t_sample is not None and (t_ns - t_sample) * _NS < self.config.fusion.odometry_stale_s
        )

    def _on_odometry(self, e: OdometryMeasured) -> None:
        vl, vr, step_s = self._odometry.add_sample(e.t_ns, e.v_left, e.v_right)
        self._travel_m += 0.5 * (abs(vl) + abs(vr)) * step_s
        dt = (e.t_ns - self._t_filter) * _NS
        if self._filter is not None and dt > 0:
            self._filter.predict(vl, vr, dt)
        self._t_filter = max(self._t_filter, e.t_ns)

    def _on_imu(self, e: ImuMeasured) -> None:
        """An IMU sample: its heading rate drives the motion model (without odometry); its
        gravity direction gives the body's tilt to the fixes (`imu_tilt`)."""
        self._motion.gyro(e.t_ns, e.gyro[2])
        # The body's own acceleration must come out of the specific force: only measured
        # wheel speeds say it (the motion model's speed moves in steps at each fix, and its
        # differences read as degrees of pitch), so without odometry the tilt is not used.
        if self.config.imu.enabled and not self._model_drives(e.t_ns):
            speed = 0.5 * (self._odometry.speeds[0] + self._odometry.speeds[1])
            self._gravity.sample(e.t_ns, e.accel, speed, e.gyro[2])

    def _motion_bound_px(self, t0_ns: int, t1_ns: int) -> float:
        """Bound on a spot's image motion between two times: from odometry (with 20 % slack)
        when there is any, else from the maximum speed and turn rate."""
        track = self._odometry
        scale = self._tracker.scale_px_per_m
        if track.t_sample_ns is None:
            dt = abs(t1_ns - t0_ns) * _NS
            speed, omega = self.robot.max_speed, self._tracker.max_angular_speed_rad_s
            if self.config.motion.enabled:  # the motion model's bounds (from rest at start)
                speed, omega = self._motion.speed_bounds(max(t0_ns, t1_ns))
            return dt * (speed * scale + omega * self._half_diag)
        a, b = track.pose_at(t0_ns), track.pose_at(t1_ns)
        move = math.hypot(b[0] - a[0], b[1] - a[1]) * scale
        turn = abs(float(wrap_angle(b[2] - a[2]))) * self._half_diag
        return 1.2 * (move + turn) + 1.0

    # -- frames --------------------------------------------------------------------------------
    def _on_frame(self, e: FrameObserved | SpotsObserved) -> PoseEstimate | NoPose:
        t = e.t_ns
        base = self._advance(t, *self._odometry.speeds)
        dt_frame = min((t - self._t_frame) * _NS, 1.0) if self._t_frame is not None else 0.0
        if dt_frame > 0:
            self._frame_interval_s = dt_frame
        self._facts = {"gap_s": dt_frame, "typical_gap_s": self._typical_gap_s}
        if 0 < dt_frame < 1.0:
            g = self._typical_gap_s
            self._typical_gap_s = dt_frame if g == 0 else min(g + 0.1 * (dt_frame - g), dt_frame)
        self._t_frame = t
        self._odometry.mark(t)
        used: tuple[int, ...] = ()
        self._expected = ()
        if self._filter is None or self._mode in ("identifying", "lost"):
            spots = self._tracker.full_spots(e)
            if self._passive.active:  # lights that cannot blink: by geometry
                fix = self._passive_fix(t, spots)
            else:
                lit = self._leds.lit_for_evidence(t, self.config.identification)
                self._identifier.observe(t, lit, spots.pixels, spots.intensities)
                fix = self._fix_from_sightings(t)
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
            self._widen_unexplained(t)
            used = self._track(e, dt_frame)
            self._mode = "landmark" if used else "dead_reckoning"
            if used:
                self._learn_liveness(t)
            if used and self.calibration is not None and not self._reseeded:
                self._self_calibrate(t)
        self._commit = self._commit or bool(used)
        if used:
            self._motion_fixed(t, used)
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
        fresh = self._fresh_odometry(e.t_ns)
        track = self._odometry
        since = 0.0
        if fresh and track.t_sample_ns is not None:
            since = (e.t_ns - track.t_sample_ns) * _NS
            since = min(since, 1.5 * (track.interval_s or since))
        self._tracker.imu_tilt = self._gravity.at(e.t_ns) if self.config.imu.enabled else None
        unpredicted = None
        if self._model_drives(e.t_ns):
            unpredicted = self._motion.unpredicted_bounds()
        result = self._tracker.step(
            self._filter,
            e,
            dt_frame_s=dt_frame,
            fresh_odometry=fresh,
            unpredicted_bounds=unpredicted,
            since_sample_s=since,
            travel_since_fix_m=self._travel_m,
            candidates=cand,
            spots=spots,
            reacquire=reacquire,
        )
        self._expected = result.expected
        self._reseeded = False
        self._facts["unexplained"] = result.unexplained
        self._facts["rejected_fix"] = result.rejected is not None
        if result.used:
            self._fix_run.fused(e.t_ns, self._filter.pose, self._filter.covariance, result.used)
        elif not reacquire and result.rejected is not None:
            result = result._replace(used=self._reseed(e.t_ns, result.rejected))
        if result.used:
            self._rejections = 0
            self._travel_m = 0.0
        elif result.unexplained:
            self._rejections += 1
        if not result.unexplained:
            self._t_explained = e.t_ns
        return result.used

    def _reseed(self, t_ns: int, fix: PoseFix) -> tuple[int, ...]:
        """A good fix the filter rejected: when it completes (or continues) a run of such
        fixes that form one track the robot could have driven by itself (`fix_run`: the
        odometry is what is wrong, a stall, a spinning wheel, a bump), the filter is re-seeded
        at it; returns its IDs (empty: not taken). The odometry's track is broken there, so
        the self-calibration starts a new one."""
        if self._filter is None or not self._fix_run.offer(t_ns, fix):
            return ()
        used = self._tracker.adopt_rejected(self._filter)
        if used:
            self._reseeded = True
            if self.calibration is not None:
                self.calibration.break_track()
        return used

    def _widen_unexplained(self, t_ns: int) -> None:
        """After frames whose spots no fix explained, the robot may have been moved without
        its odometry knowing (a kidnap): once `carry_speed_m_s` x the time since the last
        explained frame reaches half the landmark spacing (a shorter stretch, a bump or a
        glint, cannot pair a spot with another landmark's prediction and is tracked through
        as before), this frame's spots are matched with the position sigma widened to it
        (the frame's copy of the filter; kept only with a fix). Past `reacquire_sigma_m` a
        match needs the geometric check, which on a regular grid finds the pose one spacing
        away as good as the old one and takes neither."""
        if self._filter is None or self._rejections == 0:
            return
        sigma = self.config.fusion.carry_speed_m_s * (t_ns - self._t_explained) * _NS
        if sigma < 0.5 * self._tracker.spacing_m:
            return  # too short a carry to pair a spot with another landmark's prediction
        P = self._filter.covariance_rows
        var = sigma * sigma - min(P[0][0], P[1][1])
        if var > 0:
            self._filter.inflate(var, 0.0)

    def _relocalize(self, t_ns: int, spots: Spots) -> tuple[int, ...]:
        """Re-localization without LEDs: while lost (or identifying from a prior), the
        hypothesis set carried over frames (seeded around where it got lost, within the
        distance odometry has driven since; or around the prior); after long dead
        reckoning, one frame around the filter's pose, every `every_s`."""
        if self._filter is None or self._leds.changing:
            return ()
        cand = None if self._leds.lit is None else self._leds.lit_rows()
        if self._mode in ("lost", "identifying"):
            odo = self._odometry.pose
            prior = None  # identifying with a prior: the filter's pose and covariance
            if self._mode == "lost":
                x, y, th, sigma0, var_th, odo0 = self._lost_at
                sigma = sigma0 + math.hypot(odo[0] - odo0[0], odo[1] - odo0[1])
                prior = ((x, y, th), np.diag([sigma**2, sigma**2, var_th]))
            fix = self._tracker.relocalize(
                self._filter, spots, cand, prior=prior, hypotheses=self._hypotheses,
                t_ns=t_ns, odometry_pose=odo, miss_weights=self._miss_weights(),
            )  # fmt: skip
        else:
            every = self.config.relocalization.every_s
            if self._t_relocalized is not None and (t_ns - self._t_relocalized) * _NS < every:
                return ()
            self._t_relocalized = t_ns
            fix = self._tracker.relocalize(
                self._filter, spots, cand, miss_weights=self._miss_weights()
            )
        if fix is None:
            return ()
        self._reset_filter(fix.x, fix.y, fix.theta, fix.covariance, t_ns)
        return fix.landmark_ids

    def _learn_liveness(self, t_ns: int) -> None:
        """A fused frame (at most every `score_every_s`): which landmarks predicted well in
        view were detected (`LandmarkLiveness.observe_frame`)."""
        every = self.config.relocalization.score_every_s
        fused = self._tracker.last_fused
        if fused is None or self._filter is None:
            return
        if self._t_liveness is not None and (t_ns - self._t_liveness) * _NS < every:
            return
        self._t_liveness = t_ns
        index = self.map.index_of
        predicted = np.array([index(i) for i in self._expected], dtype=np.int64)
        x, y, th = (float(v) for v in self._filter.state)
        rows, px, _ = fused
        self._liveness.observe_frame(
            self.camera, (x, y, th), self.map.positions, predicted,
            np.asarray(rows, dtype=np.int64), np.asarray(px, dtype=np.float64).reshape(-1, 2),
        )  # fmt: skip

    def _miss_weights(self) -> FloatArray:
        """What each landmark's absence weighs against a hypothesis (`LandmarkLiveness`),
        one per map row; fixed while lost (nothing is learnt then)."""
        return self._liveness.miss_log_lr()

    def _self_calibrate(self, t_ns: int) -> None:
        """Feed the fused fix to the online self-calibration; when it hands back a corrected
        camera, use it from now on, and move the pose to where this frame's spots put it
        through the corrected camera (the filter's belief stays, read through the better
        lens)."""
        fused = self._tracker.last_fused
        if self.calibration is None or fused is None or self._filter is None:
            return
        rows, px, fix = fused
        completed = self.calibration.wants(t_ns, len(rows)) and self.calibration.observe(
            t_ns,
            px,
            self.map.positions[rows],
            (fix.x, fix.y, fix.theta),
            self._odometry.pose_at(t_ns),
            fix.floor,
        )
        if not completed:  # a completed window's work goes on a step a frame, not all at once
            self.calibration.step()
        update = self.calibration.take_update()
        if update is None:
            return
        P = self.map.positions[rows]
        pose = (fix.x, fix.y, fix.theta)
        sigma = [self._tracker.noise.sigma_px(u, v) for u, v in px]
        # on the floor the fix stood on (its tilt and height), not the map's level one
        on = None if fix.floor is None else (
            (float(fix.floor[0]), float(fix.floor[1]), float(fix.floor[2])), np.eye(3) * 1e-12
        )  # fmt: skip
        moved = solve_pose(update.camera, px, P, initial=pose, pixel_sigma_px=sigma,
                           floor_prior=on)  # fmt: skip
        if moved is not None:
            self._filter.shift(moved.x - fix.x, moved.y - fix.y,
                               float(wrap_angle(moved.theta - fix.theta)))  # fmt: skip
        self.camera = update.camera
        self._tracker.camera = update.camera
        self._tracker.set_map(self.map)  # scale, reach and the noise model of the new lens

    def _passive_fix(self, t_ns: int, spots: Spots) -> PoseFix | None:
        """Passive landmarks identified by geometry (`PassiveIdentifier`: around the
        filter's pose when there is one, a start pose or where it got lost; else anywhere),
        solved and verified by reprojection."""
        prior = None if self._filter is None else (self._filter.pose, self._filter.covariance)
        odo = self._odometry.pose
        found = self._passive.identify(t_ns, self.camera, spots.pixels, odo, prior)
        if found is None:
            return None
        pose, pairs = found
        px, noise = spots.pixels, self._tracker.noise
        sigma = [
            noise.sigma_px(float(px[s, 0]), float(px[s, 1]), self.map.sigma_at(r)) for r, s in pairs
        ]
        fix = fix_from_pairs(self.camera, self.map, spots.pixels, pairs, sigma, pose,
                             outlier_sigma=self.config.passive.outlier_sigma)  # fmt: skip
        if fix is not None:
            self._passive.clear()
        return fix

    def _fix_from_sightings(self, t_ns: int) -> PoseFix | None:
        """First fix from identified landmarks, each carried by odometry to the frame time."""
        sightings = list(self._identifier.sightings.values())
        if len(sightings) < self.config.identification.landmarks_needed:
            return None
        fc = self.config.fusion
        fix = first_fix(
            self.camera,
            self.map,
            sightings,
            self._odometry.pose_at,
            t_ns,
            pixel_sigma_px=fc.pixel_sigma_px,
            max_residual_px=fc.max_residual_px,
        )
        if fix is None:
            # Inconsistent sightings: keep the newest (a fresh one, near the robot), find
            # another in view of it.
            self._identifier.keep_newest()
            self._view.reset()
        return fix

    def _order_by_view(self, t_ns: int) -> None:
        """With one landmark identified (or showing itself), probe first the candidates in
        view of where the robot can be when the next probe lands (`order_by_view`: the
        sighting's ray from its odometry pose, the odometry since, extrapolated at the
        current wheel speeds over the measured command latency and the frames a probe
        needs); again once odometry has moved `reorder_distance_m` or turned
        `reorder_turn_rad` since the last ordering."""
        anchor = self._identifier.anchor
        if anchor is None or anchor.landmark_id not in self.map:
            return
        ic = self.config.identification
        odo = self._odometry.pose_at(t_ns)
        if not self._view.due(anchor, odo):
            return
        frame_s = self._frame_interval_s or 0.0
        lead_s = self._identifier.probes.latency_s + ic.frames_per_led * frame_s
        x, y, th = self._odometry.pose
        landing = integrate_arc(x, y, th, *self._odometry.speeds, lead_s, self.robot.wheel_base)
        then = anchor.odometry or self._odometry.pose_at(anchor.t_ns)
        ranked = order_by_view(
            self.camera, self.map.ids.tolist(), self.map.positions, anchor.landmark_id,
            anchor.pixel, then, landing,
            headings=ic.view_headings, inner_radius_px=self._identifier.inner_radius_px,
        )  # fmt: skip
        order, fresh = self._view.ordered(anchor, odo, ranked)
        self._identifier.prefer(order, come_into_view=fresh)

    # -- modes and outputs ---------------------------------------------------------------------
    def _check_lost(self, t_ns: int) -> None:
        if self._filter is None or self._mode in ("identifying", "lost"):
            return
        fc = self.config.fusion
        sigma = position_sigma_m(self._filter.covariance_rows)
        if sigma > fc.lost_sigma_m or self._rejections >= fc.lost_after_rejections:
            self._mode = "lost"
            if self.calibration is not None:
                self.calibration.break_track()
            self._start_identification()
            self._commit = True
            self._lost_by_disagreement = sigma <= fc.lost_sigma_m
            if sigma < fc.lost_sigma_m or self._rejections > 0:
                # The observations disagree with the pose (a kidnapped robot, put down
                # anywhere, facing anywhere): widen its uncertainty so that a map-consistent
                # re-acquisition can correct it.
                x, y, th = (float(v) for v in self._filter.state)
                cov = self._filter.covariance
                cov[:2, :2] = np.eye(2) * max(fc.lost_sigma_m, sigma) ** 2
                cov[:2, 2] = cov[2, :2] = 0.0
                cov[2, 2] = max(float(cov[2, 2]), fc.lost_sigma_rad**2)
                self._filter.reset(x, y, th, cov)
            x, y, th = (float(v) for v in self._filter.state)
            var_th = float(self._filter.covariance[2, 2])
            sigma0 = max(position_sigma_m(self._filter.covariance_rows), fc.lost_sigma_m)
            self._lost_at = (x, y, th, sigma0, var_th, self._odometry.pose)
            self._hypotheses.clear()
            self._fix_run.clear()

    def _start_identification(self) -> None:
        ids = self.map.ids.tolist()
        if self._filter is not None:
            x, y = float(self._filter.state[0]), float(self._filter.state[1])
            d = np.hypot(self.map.positions[:, 0] - x, self.map.positions[:, 1] - y)
            ids = [int(self.map.ids[i]) for i in np.argsort(d, kind="stable")]
        self._identifier.restart(ids)
        self._view.reset()
        self._leds.restart_sweep(not self._passive.active)  # passive lights are never switched

    def _requests(self, t_ns: int) -> list[Output]:
        """LED requests of an identification in progress (the last one lights all)."""
        leds = self._leds
        req = leds.all_lit_request(t_ns)
        if req is not None:
            return [req]
        if not leds.sweeping:
            return []
        self._order_by_view(t_ns)
        return list(leds.sweep_request(t_ns, self._identifier))

    def _output(self, t_ns: int, used: tuple[int, ...]) -> PoseEstimate | NoPose:
        if self._filter is None:
            facts = self._frame_facts(t_ns, None, used)
            code = reason_for(facts)
            text = "" if code is None else reason_text(code, facts)
            return NoPose(t_ns, self._mode, reason=code, reason_text=text)
        x, y, theta = self._filter.output_pose
        sx, sy, sth = self._filter.pose
        offset = (x - sx, y - sy, float(wrap_angle(theta - sth)))
        qc = self.config.quality
        cov = published_covariance(self._filter.covariance, self._mode, offset, qc)
        deviation = deviation_radius_m(cov)
        facts = self._frame_facts(t_ns, (x, y, theta), used)
        code = reason_for(facts)
        est = PoseEstimate(
            t_ns=t_ns,
            x=x,
            y=y,
            theta=theta,
            covariance=cov,
            mode=self._mode,
            landmark_ids=used,
            expected_ids=self._expected,
            quality=quality_from_deviation(deviation, qc),
            deviation_m=deviation,
            reason=code,
            reason_text="" if code is None else reason_text(code, facts),
        )
        self._latest = est
        return est

    def _frame_facts(
        self, t_ns: int, pose: tuple[float, float, float] | None, used: tuple[int, ...]
    ) -> FrameFacts:
        """What explains this frame's lack of a fix (`pose_quality.reason_for`); the ceiling
        in view is worked out only for a pose without a fix."""
        f = self._facts
        track = self._odometry
        age = math.inf if track.t_sample_ns is None else (t_ns - track.t_sample_ns) * _NS
        ic = self.config.identification
        leds = self._leds
        awaiting = leds.awaiting(t_ns, ic.led_timeout_s)
        in_view = lit = switching = 0
        dark: tuple[int, ...] = ()
        dead: tuple[int, ...] = ()
        if pose is not None and not used and self._mode in ("landmark", "dead_reckoning"):
            heights = self.map.positions[:, 2] - float(self.camera.T_body_camera[2, 3])
            reach = visible_radius_m(self.camera, float(np.max(heights, initial=0.0)))
            rows = np.flatnonzero(landmarks_in_view(self.camera, pose, self.map.positions, reach))
            ids = [int(self.map.ids[r]) for r in rows]
            in_view = len(ids)
            switching = sum(1 for i in ids if i in leds.changing)
            dark = tuple(
                i for i in ids
                if leds.lit is not None and i not in leds.lit and i not in leds.changing
            )  # fmt: skip
            lit_rows = [
                r for r, i in zip(rows, ids, strict=True)
                if i not in leds.changing and i not in dark
            ]  # fmt: skip
            lit = len(lit_rows)
            live = self._liveness
            dead = tuple(
                int(self.map.ids[r]) for r in lit_rows if not live.lit[r] and live.unseen[r] >= 3
            )
        return FrameFacts(
            mode=self._mode,
            fused=bool(used),
            lost_by_disagreement=self._lost_by_disagreement,
            in_view=in_view,
            lit_in_view=lit,
            switching_in_view=switching,
            dark_ids=dark,
            dead_ids=dead,
            unexplained=bool(f.get("unexplained", False)),
            rejected_fix=bool(f.get("rejected_fix", False)),
            rejections=self._rejections,
            gap_s=float(f.get("gap_s", 0.0)),
            typical_gap_s=float(f.get("typical_gap_s", 0.0)),
            skipped=bool(f.get("skipped", False)),
            odometry_age_s=age,
            odometry_stale_s=self.config.fusion.odometry_stale_s,
            awaiting_leds=awaiting,
        )
