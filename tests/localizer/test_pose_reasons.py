"""Every reason code of `pose_quality`, each caused by a scenario the localizer lives through:
spots from the true pose (eq. 3), wheel odometry, LEDs that obey or ignore the requests."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from localizer.camera import predict_pixels
from localizer.config import FusionConfig, LocalizerConfig
from localizer.events import (
    LedRequest,
    LedsChanged,
    NoPose,
    OdometryMeasured,
    PoseEstimate,
    SpotsObserved,
)
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.odometry import integrate_arc
from localizer.pose_quality import REASON_CODES, REASON_TEXT
from localizer.robot import RobotGeometry
from sim.cameras import wide_angle_camera

ROBOT = RobotGeometry(wheel_base=0.36, max_speed=1.0)
CAMERA = wide_angle_camera("pinhole")
FRAME_NS = 33_333_333
ODOM_NS = 10_000_000
# a triangle at the origin, a lone landmark at x = 9 m, a triangle with a dead LED at 18 m
MAP = LandmarkMap(
    np.array([1, 2, 3, 10, 21, 22, 23]),
    np.array([
        [0.0, 0.0, 2.5], [1.2, 0.0, 2.5], [0.6, 1.04, 2.45],
        [9.0, 0.0, 2.5],
        [18.0, 0.0, 2.5], [19.2, 0.0, 2.5], [18.6, 1.04, 2.5],
    ]),
)  # fmt: skip


@dataclass
class Scene:
    """A robot under `MAP`: `step` advances time by one frame, driving at the given wheel
    speeds (the truth integrates the true speeds, odometry reports the measured ones)."""

    loc: Localizer
    pose: tuple[float, float, float] = (0.45, 0.3, 0.2)
    t_ns: int = 0
    lit: set[int] = field(default_factory=lambda: set(MAP.ids.tolist()))
    dead: set[int] = field(default_factory=set)
    radio: bool = True  # LED requests are applied and confirmed
    outputs: list[PoseEstimate | NoPose] = field(default_factory=list)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(4))

    def step(
        self,
        v: float = 0.0,
        *,
        odometry: bool = True,
        measured_v: float | None = None,
        spots: str = "true",
        frame: bool = True,
    ) -> PoseEstimate | NoPose | None:
        """One frame interval: odometry every 10 ms (unless `odometry` is False), then the
        frame. `spots`: "true" (the lit landmarks from the true pose), "none" (the lens
        covered), "scrambled" (each spot moved 25 px its own way: reflections)."""
        t0 = self.t_ns
        self.t_ns += FRAME_NS
        for t in range(t0 + ODOM_NS, self.t_ns, ODOM_NS):
            self.pose = integrate_arc(*self.pose, v, v, ODOM_NS * 1e-9, ROBOT.wheel_base)
            if odometry:
                mv = v if measured_v is None else measured_v
                self._handle(OdometryMeasured(t, mv, mv))
        if not frame:
            return None
        on = sorted(i for i in self.lit if i not in self.dead)
        rows = [MAP.index_of(i) for i in on]
        px, ok = predict_pixels(CAMERA, T_world_body_from_pose(*self.pose), MAP.positions[rows])
        px = px[ok & (px[:, 0] >= 0) & (px[:, 0] < 640) & (px[:, 1] >= 0) & (px[:, 1] < 480)]
        px = px + self.rng.normal(0.0, 0.2, px.shape)
        if spots == "none":
            px = px[:0]
        elif spots == "scrambled":
            angles = self.rng.uniform(0, 2 * math.pi, len(px))
            px = px + 25.0 * np.column_stack([np.cos(angles), np.sin(angles)])
        n = len(px)
        event = SpotsObserved(self.t_ns, px, np.full(n, 1000.0), np.full(n, 12.0))
        out = [o for o in self._handle(event) if isinstance(o, PoseEstimate | NoPose)]
        assert len(out) == 1
        self.outputs.append(out[0])
        return out[0]

    def _handle(self, event: object) -> list[object]:
        outs: list[object] = list(self.loc.handle(event))  # type: ignore[arg-type]
        for o in outs:
            if isinstance(o, LedRequest) and self.radio:
                ids = set(MAP.ids.tolist())
                self.lit = ids - set(o.dark) if o.all_lit else set(o.lit)
                full = self.lit == ids
                lit = frozenset() if full else frozenset(self.lit)
                self.loc.handle(LedsChanged(self.t_ns + 1, lit, all_lit=full))
        return outs

    def set_leds(self, lit: set[int]) -> None:
        """The LED schedule switches the ceiling (confirmed by the radio)."""
        self.lit = set(lit)
        self.loc.handle(LedsChanged(self.t_ns + 1, frozenset(lit)))

    def fix(self) -> PoseEstimate:
        """Frames until a landmark fix."""
        for _ in range(120):
            out = self.step()
            if isinstance(out, PoseEstimate) and out.mode == "landmark":
                return out
        raise AssertionError(f"no fix: {[o.mode for o in self.outputs[-5:]]}")

    def drive_to(self, x: float, v: float = 1.0, **kw: object) -> list[str | None]:
        """Drive along +x (heading 0) until the true x passes `x`; the reasons on the way."""
        seen: list[str | None] = []
        while self.pose[0] < x:
            out = self.step(v, **kw)  # type: ignore[arg-type]
            assert out is not None
            seen.append(out.reason)
        return seen


def scene(config: LocalizerConfig | None = None, **kw: object) -> Scene:
    return Scene(Localizer(CAMERA, MAP, ROBOT, config), **kw)  # type: ignore[arg-type]


def driving_scene() -> Scene:
    """Fixed under the first triangle, heading along +x."""
    s = scene(pose=(0.45, 0.3, 0.0))
    s.fix()
    return s


def test_every_code_has_a_sentence() -> None:
    assert set(REASON_TEXT) == set(REASON_CODES)


def test_landmark_fix_has_no_reason_and_a_high_quality() -> None:
    s = scene()
    est = s.fix()
    for _ in range(10):
        est = s.step()  # type: ignore[assignment]
    assert isinstance(est, PoseEstimate) and est.mode == "landmark"
    assert est.reason is None and est.reason_text == ""
    # the published floor (1 cm a side on a fix) bounds it from below
    assert est.deviation_m is not None and 0.0245 < est.deviation_m < 0.035
    assert est.quality is not None and est.quality > 0.95


def test_identifying() -> None:
    s = scene()
    reasons = [s.step().reason for _ in range(6)]  # type: ignore[union-attr]
    assert "identifying" in reasons
    assert all(isinstance(o, NoPose) and o.quality == 0.0 for o in s.outputs)


def test_waiting_for_radio() -> None:
    s = scene(radio=False)
    reasons = [s.step().reason for _ in range(6)]  # type: ignore[union-attr]
    assert reasons[0] == "identifying"  # no request yet
    assert set(reasons[1:]) == {"waiting_for_radio"}


def test_no_landmark_in_view() -> None:
    s = driving_scene()
    reasons = s.drive_to(5.5)
    assert reasons[-1] == "no_landmark_in_view"


def test_one_landmark_only() -> None:
    s = driving_scene()
    s.drive_to(9.0)
    out = s.step()
    assert out is not None and out.reason == "one_landmark_only"
    assert "only one landmark" in out.reason_text


def test_landmarks_dark_by_the_schedule() -> None:
    s = scene()
    s.fix()
    s.set_leds({10, 21, 22, 23})  # the triangle above the robot switched off
    out = s.step()
    assert out is not None and out.mode == "dead_reckoning"
    assert out.reason == "landmarks_dark"
    assert out.reason_text.startswith("the 3 landmark(s) in view are switched off")


def test_a_dead_led() -> None:
    s = scene(pose=(18.7, 0.45, 0.2), dead={23})
    s.fix()
    for _ in range(60):  # tracking sees 21 and 22, never 23 (every score_every_s)
        s.step()
    s.set_leds({1, 2, 3, 10, 21, 23})  # the schedule darkens 22: one working LED is left
    out = s.step()
    assert out is not None and out.reason == "landmark_dead"
    assert "23" in out.reason_text


def test_landmarks_not_seen_when_the_lens_is_covered() -> None:
    s = scene()
    s.fix()
    out = s.step(spots="none")
    assert out is not None and out.reason == "landmarks_not_seen"


def test_spots_that_do_not_fit_are_rejected_as_glints() -> None:
    s = scene()
    s.fix()
    out = s.step(spots="scrambled")
    assert out is not None and out.mode == "dead_reckoning"
    assert out.reason == "spots_rejected_glint"


def test_a_bumped_robot_fails_the_gate_then_the_odometry_is_blamed() -> None:
    s = scene()
    s.fix()
    s.pose = (s.pose[0] + 0.05, s.pose[1], s.pose[2])  # pushed 5 cm, the wheels never turned
    reasons = [s.step().reason for _ in range(5)]  # type: ignore[union-attr]
    assert reasons[0] == "spots_rejected_gate"
    assert "odometry_slipping" in reasons[2:]


def test_kidnapped_suspected() -> None:
    cfg = LocalizerConfig(fusion=FusionConfig(lost_after_rejections=5))
    s = scene(cfg)
    s.fix()
    s.pose = (0.75, 0.1, 1.2)  # picked up, turned by a radian, put down 30 cm away
    reasons = [s.step().reason for _ in range(8)]  # type: ignore[union-attr]
    assert "kidnapped_suspected" in reasons
    lost = [o for o in s.outputs if o.mode == "lost"]
    assert lost and all(o.reason == "kidnapped_suspected" for o in lost)


def test_lost_when_the_uncertainty_grows() -> None:
    cfg = LocalizerConfig(fusion=FusionConfig(lost_sigma_m=0.05))
    s = scene(cfg, pose=(0.45, 0.3, 0.0))
    s.fix()
    reasons = s.drive_to(14.0)
    assert reasons[-1] == "lost"
    assert s.outputs[-1].mode == "lost"


def test_camera_stale() -> None:
    s = scene()
    s.fix()
    s.set_leds(set())  # no fix to hide behind
    for _ in range(10):
        s.step(frame=False)  # a third of a second without a frame
    out = s.step()
    assert out is not None and out.reason == "camera_stale"
    assert out.reason_text.startswith("no camera frame for 0.")


def test_frames_dropped() -> None:
    s = scene()
    s.fix()
    s.step(frame=False)
    out = s.loc.skip_frame(s.t_ns)
    assert out.reason == "frames_dropped"


def test_odometry_stale() -> None:
    s = scene()
    s.fix()
    s.set_leds(set())
    reasons = [s.step(odometry=False).reason for _ in range(12)]  # type: ignore[union-attr]
    assert reasons[0] == "landmarks_dark"
    assert reasons[-1] == "odometry_stale"


def test_each_code_is_caused_by_a_scenario_above() -> None:
    source = Path(__file__).read_text(encoding="utf-8").split("def test_each_code")[0]
    assert [c for c in REASON_CODES if f'"{c}"' not in source] == []
