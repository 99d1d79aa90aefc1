"""The identification wizard as a state machine, driven without a browser or a server: a
little synthetic site (true LED positions, a moving robot, the spots its camera would see,
LED switches applied at once) feeds it events and carries out its outputs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from commissioning.types import Candidate, MapLandmark
from commissioning.wizard import (
    Cancel,
    Confirm,
    Finished,
    FrameSeen,
    IdentificationWizard,
    LedsSeen,
    PoseSeen,
    RadioSwitched,
    SaveLandmark,
    Skip,
    Start,
    SwitchAnyway,
    SwitchLandmark,
    SwitchRadio,
    WizardConfig,
    WizardOutput,
)
from localizer.camera import predict_pixels
from localizer.events import PoseEstimate
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera

CAM = wide_angle_camera("pinhole")
TRUTH = {10 + 3 * j + i: (1.2 * i, 1.2 * j, 2.5) for j in range(3) for i in range(3)}
FRAME_NS = 33_000_000


class Site:
    """Truth, one measuring robot r1 (moving at 0.2 m/s along x) and a tracking robot r2."""

    def __init__(self, truth: dict[int, tuple[float, float, float]], *, r2_uses: tuple[int, ...]):
        self.truth = {k: np.array(v) for k, v in truth.items()}
        self.radios: dict[str, np.ndarray] = {}
        self.glints: list[tuple[np.ndarray, float]] = []  # position, chance to be detected
        self.dark: set[int] = set()
        self.radio_on: set[str] = set()
        self.t_ns = 1_000_000_000
        self.r2_uses = r2_uses
        self.saved: list[SaveLandmark] = []
        self.finished: list[Finished] = []
        self.dark_log: list[tuple[int, frozenset[int]]] = []
        self.rng = np.random.default_rng(3)

    def pose_r1(self) -> tuple[float, float, float]:
        return (0.9 + 0.2 * (self.t_ns * 1e-9 - 1.0) % 1.0, 1.1, 0.2)

    def leds(self) -> LedsSeen:
        return LedsSeen(self.t_ns, frozenset(self.truth) - self.dark)

    def carry_out(self, wiz: IdentificationWizard, outs: list[WizardOutput]) -> None:
        for out in outs:
            if isinstance(out, SwitchLandmark):
                (self.dark.discard if out.on else self.dark.add)(out.landmark_id)
                self.dark_log.append((self.t_ns, frozenset(self.dark)))
                self.carry_out(wiz, wiz.handle(self.leds()))
            elif isinstance(out, SwitchRadio):
                (self.radio_on.add if out.on else self.radio_on.discard)(out.address)
                self.carry_out(wiz, wiz.handle(RadioSwitched(self.t_ns, out.address, out.on)))
            elif isinstance(out, SaveLandmark):
                self.saved.append(out)
            elif isinstance(out, Finished):
                self.finished.append(out)

    def frame(self) -> FrameSeen:
        x, y, th = self.pose_r1()
        lit = [self.truth[i] for i in sorted(self.truth) if i not in self.dark]
        lit += [self.radios[a] for a in sorted(self.radio_on) if a in self.radios]
        lit += [p for p, chance in self.glints if self.rng.random() < chance]
        px, ok = predict_pixels(CAM, T_world_body_from_pose(x, y, th), np.array(lit))
        px = px[ok] + self.rng.normal(0.0, 0.2, (int(ok.sum()), 2))
        cov = np.diag([1e-4, 1e-4, 1e-5])
        pose = PoseEstimate(self.t_ns, x, y, th, cov, "landmark", (10, 11, 13, 14))
        return FrameSeen("r1", pose, px)

    def run(self, wiz: IdentificationWizard, seconds: float) -> None:
        """Frames of r1 (30 per second) and poses of r2, with the LED switches carried out."""
        for _ in range(round(seconds / (FRAME_NS * 1e-9))):
            self.t_ns += FRAME_NS
            cov = np.diag([1e-4, 1e-4, 1e-5])
            r2 = PoseEstimate(self.t_ns, 1.2, 1.2, 0.0, cov, "landmark", self.r2_uses)
            self.carry_out(wiz, wiz.handle(PoseSeen("r2", r2)))
            self.carry_out(wiz, wiz.handle(self.frame()))


def start(site: Site, wiz: IdentificationWizard, queue: tuple[Candidate, ...],
          mapped: dict[int, tuple[float, float, float]]) -> None:  # fmt: skip
    lms = {i: MapLandmark(i, *p) for i, p in mapped.items()}
    site.carry_out(wiz, wiz.handle(site.leds()))
    event = Start(site.t_ns, "r1", CAM, queue, lms, 2.5, ("r1", "r2"))
    site.carry_out(wiz, wiz.handle(event))


def test_a_moved_landmark_is_measured_while_the_robot_moves_and_only_one_led_goes_dark() -> None:
    site = Site(TRUTH, r2_uses=(10, 11, 12, 13, 14))
    wrong = dict(TRUTH)
    wrong[14] = (TRUTH[14][0] + 0.2, TRUTH[14][1] - 0.1, 2.5)  # the map is 22 cm off
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(14),), wrong)
    assert not wiz.status().can_confirm  # nothing measured yet: Confirm is not offered
    with pytest.raises(ValueError, match="nothing measured yet"):
        wiz.handle(Confirm(site.t_ns))
    site.run(wiz, 4.0)
    st = wiz.status()
    assert st.phase == "measuring" and st.can_confirm, st.prompt
    assert st.measurement is not None and st.measurement.samples >= 5
    np.testing.assert_allclose(st.measurement.position, TRUTH[14], atol=0.01)
    assert st.measurement.plausibility.distance_m == pytest.approx(0.2236, abs=0.01)
    assert not st.measurement.plausibility.far
    # it only ever darkened landmark 14, never the ceiling
    assert site.dark_log and all(dark <= {14} for _, dark in site.dark_log)
    site.carry_out(wiz, wiz.handle(Confirm(site.t_ns)))
    assert [s.candidate.landmark_id for s in site.saved] == [14]
    np.testing.assert_allclose(site.saved[0].position, TRUTH[14], atol=0.01)
    assert site.dark == set() and site.finished[0].saved == (14,)


def test_a_far_measurement_is_flagged_and_needs_accept_far() -> None:
    site = Site(TRUTH, r2_uses=(10, 11, 12, 13, 14))
    wrong = dict(TRUTH)
    wrong[14] = (TRUTH[14][0] + 4.0, TRUTH[14][1] + 2.5, 2.5)  # 4.7 m off
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(14),), wrong)
    site.run(wiz, 4.0)
    st = wiz.status()
    assert st.measurement is not None and st.measurement.plausibility.far
    assert st.measurement.plausibility.distance_m == pytest.approx(4.72, abs=0.02)
    assert not st.can_confirm and st.needs_accept_far and "far; confirm only if" in st.prompt
    with pytest.raises(ValueError, match="far from the map"):
        wiz.handle(Confirm(site.t_ns))
    assert site.saved == []
    site.carry_out(wiz, wiz.handle(Confirm(site.t_ns, accept_far=True)))
    np.testing.assert_allclose(site.saved[0].position, TRUTH[14], atol=0.01)


def test_it_waits_rather_than_cost_a_robot_its_fix_and_asks_after_a_while() -> None:
    site = Site(TRUTH, r2_uses=(14, 15))  # r2 tracks with 14 and one other only
    cfg = WizardConfig(wait_fix_s=2.0)
    wiz = IdentificationWizard(cfg)
    start(site, wiz, (Candidate(14),), TRUTH)
    site.run(wiz, 1.0)
    st = wiz.status()
    assert st.phase == "waiting" and st.waiting_for == ("r2",)
    assert "would cost r2 its landmark fix" in st.prompt and "switch anyway" not in st.prompt
    assert site.dark_log == []  # never darkened
    site.run(wiz, 2.0)
    assert "switch anyway" in wiz.status().prompt
    assert site.dark_log == []
    site.r2_uses = (11, 12, 13, 14)  # r2 moved on: it would keep three
    site.run(wiz, 3.0)
    st = wiz.status()
    assert st.phase == "measuring" and st.can_confirm and st.waiting_for == ()


def test_switch_anyway_darkens_it_although_a_robot_depends_on_it() -> None:
    site = Site(TRUTH, r2_uses=(14, 15))
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(14),), TRUTH)
    site.run(wiz, 1.0)
    site.carry_out(wiz, wiz.handle(SwitchAnyway(site.t_ns)))
    assert site.dark == {14}
    site.run(wiz, 3.0)
    assert wiz.status().can_confirm


def test_no_spot_says_what_to_move() -> None:
    world = {**TRUTH, 99: (20.0, 20.0, 2.5)}  # lit, but far from r1
    site = Site(world, r2_uses=(10, 11, 12, 13))
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(99),), world)
    site.run(wiz, 5.0)
    st = wiz.status()
    assert st.measurement is None and not st.can_confirm
    assert "is not in r1's view" in st.prompt and "drive r1 under it" in st.prompt
    assert "(20.00, 20.00)" in st.prompt


def test_a_landmark_whose_led_never_switches_is_reported() -> None:
    site = Site(TRUTH, r2_uses=(10, 11, 12, 13))
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(99),), {**TRUTH, 99: (1.0, 1.0, 2.5)})  # its LED is dead
    site.run(wiz, 5.0)
    st = wiz.status()
    assert not st.can_confirm and "never confirmed lit" in st.prompt


def test_a_new_radio_is_lit_alone_measured_then_skipped_and_relit() -> None:
    site = Site(TRUTH, r2_uses=(10, 11, 12, 13))
    radio = "0013A20041000105"
    site.radios[radio] = np.array([1.7, 1.5, 2.5])
    site.radio_on.add(radio)  # lit when found
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(105, radio, "new radio"),), TRUTH)
    site.run(wiz, 4.0)
    st = wiz.status()
    assert st.measurement is not None and st.can_confirm, st.prompt
    np.testing.assert_allclose(st.measurement.position, site.radios[radio], atol=0.01)
    assert site.dark_log == []  # no landmark was darkened for a new radio
    site.carry_out(wiz, wiz.handle(Skip(site.t_ns)))
    assert radio in site.radio_on and site.finished[0].skipped == (105,)


def test_a_flickering_glint_is_not_measured_and_the_prompt_says_so() -> None:
    site = Site(TRUTH, r2_uses=(10, 11, 12, 13))
    radio = "0013A20041000106"
    site.radios[radio] = np.array([9.0, 9.0, 2.5])  # hangs far from r1: never in view
    site.radio_on.add(radio)
    site.glints.append((np.array([1.45, 1.2, 2.5]), 0.5))  # 25 cm beside landmark 14
    wiz = IdentificationWizard()
    start(site, wiz, (Candidate(106, radio, "new radio"),), TRUTH)
    site.run(wiz, 6.0)
    st = wiz.status()
    assert st.measurement is None and not st.can_confirm
    assert "no spot follows radio 0013A20041000106's LED in r1's view" in st.prompt, st.prompt
    assert "a spot at (1.45, 1.20) comes and goes out of step with it" in st.prompt
    assert "keep it blinking and drive r1 to where the radio hangs" in st.prompt


def test_bad_starts_and_actions_say_why() -> None:
    wiz = IdentificationWizard()
    lms = {10: MapLandmark(10, 0.0, 0.0, 2.5)}
    with pytest.raises(ValueError, match="nothing to identify"):
        wiz.handle(Start(0, "r1", CAM, (), lms, 2.5, ("r1",)))
    with pytest.raises(ValueError, match="unknown robot 'r9'"):
        wiz.handle(Start(0, "r9", CAM, (Candidate(10),), lms, 2.5, ("r1",)))
    with pytest.raises(ValueError, match="landmark 11 is not in the map"):
        wiz.handle(Start(0, "r1", CAM, (Candidate(11),), lms, 2.5, ("r1",)))
    with pytest.raises(ValueError, match="not running"):
        wiz.handle(Skip(0))
    wiz.handle(Start(0, "r1", CAM, (Candidate(10),), lms, 2.5, ("r1",)))
    with pytest.raises(ValueError, match="already running"):
        wiz.handle(Start(0, "r1", CAM, (Candidate(10),), lms, 2.5, ("r1",)))
    with pytest.raises(ValueError, match="three finite numbers"):
        wiz.handle(Confirm(0, (float("nan"), 0.0, 2.5)))
    outs = wiz.handle(Cancel(1))
    assert isinstance(outs[-1], Finished) and outs[-1].phase == "cancelled"
    assert wiz.status().phase == "cancelled" and not wiz.running


def test_the_config_is_a_frozen_dataclass_with_units() -> None:
    cfg = WizardConfig()
    assert dataclasses.is_dataclass(cfg) and cfg.far_m == 0.5 and cfg.min_agreeing == 5
