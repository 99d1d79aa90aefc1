"""The identification wizard as a sans-I/O state machine (docs/commissioning.md).

It measures, one candidate at a time, where a landmark (or a new radio from discovery) hangs,
with one chosen robot's camera, while every robot keeps tracking: it never darkens the
ceiling. A landmark of the map is darkened *alone* against the lit set for `dark_s`, then lit
again for `lit_s`, over and over (as robots identify themselves); a new radio is lit alone
and darkened again. Each lit frame gives a sample of where it is when one spot followed the
LED through `min_cycles` lit phases and the dark ones between (`commissioning.measuring`,
kept by `commissioning.sampling`); the robot may move meanwhile. Confirm is offered once
`min_agreeing` samples agree, and a position far from the map's needs an explicit "accept
far". Its tuning is `commissioning.wizard_config`, its words `commissioning.wizard_prompts`.

Before darkening a landmark it checks the robots that track: when one of them would be left
with fewer than `min_fix_landmarks` landmarks (its fix), the wizard waits and says so; after
`wait_fix_s` it asks whether to switch anyway.

Events in (`handle`): `Start`, `PoseSeen` (any robot's estimate), `FrameSeen` (the chosen
robot's spots with its estimate for that frame), `LedsSeen` (every confirmed LED state),
`RadioSwitched` (a new radio's acknowledgement), `Tick`, and the user's `Confirm`, `Skip`,
`SwitchAnyway`, `Cancel`. Outputs: `SwitchLandmark`, `SwitchRadio`, `SaveLandmark`,
`Finished`. `status()` says where it stands. Nothing here waits, sleeps or reads a clock.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from commissioning.doubt import expected_in_view
from commissioning.measuring import (
    PlacedFrame,
    place_spots,
    plausibility,
)
from commissioning.sampling import TargetSamples
from commissioning.types import Candidate, MapLandmark
from commissioning.wizard_config import WizardConfig
from commissioning.wizard_messages import (
    Cancel,
    Confirm,
    Finished,
    FrameSeen,
    LedsSeen,
    Measurement,
    Phase,
    PoseSeen,
    RadioSwitched,
    SaveLandmark,
    Skip,
    Start,
    SwitchAnyway,
    SwitchLandmark,
    SwitchRadio,
    Tick,
    WizardEvent,
    WizardOutput,
    WizardStatus,
)
from commissioning.wizard_prompts import (
    NoSpot,
    measuring_prompt,
    never_switched_prompt,
    no_spot_prompt,
    waiting_prompt,
    what,
)
from localizer.camera import CameraModel
from localizer.events import PoseEstimate


@dataclass
class _Target:
    """The candidate being measured and its LED cycle."""

    candidate: Candidate
    known: MapLandmark | None
    height: float
    want_on: bool  # the target's LED as the cycle wants it now
    sampled: TargetSamples  # its frames and the samples they gave
    since_ns: int | None = None  # when the wanted state was confirmed (None: not yet)
    asked_ns: int | None = None  # when it was last asked for
    # a new radio's LED from asking for a state until its acknowledgement may be either way
    # (a landmark's: the gateway's LED state says when it is being switched): (from, to)
    unsure: list[tuple[int, int | None]] = field(default_factory=list)
    force: bool = False
    waiting_since_ns: int | None = None
    blockers: tuple[str, ...] = ()
    started_ns: int = 0


class IdentificationWizard:
    """One site's wizard (its LEDs are shared): feed it events, carry out what it returns."""

    def __init__(self, config: WizardConfig | None = None) -> None:
        self.config = config or WizardConfig()
        self._phase: Phase = "idle"
        self._robot = ""
        self._camera: CameraModel | None = None
        self._queue: tuple[Candidate, ...] = ()
        self._index = 0
        self._landmarks: dict[int, MapLandmark] = {}
        self._ceiling_z = 2.5
        self._poses: dict[str, PoseEstimate] = {}
        self._leds: deque[LedsSeen] = deque()
        self._radio_on: dict[str, tuple[bool, int]] = {}  # address -> (on, since t_ns)
        self._target: _Target | None = None
        self._saved: list[int] = []
        self._skipped: list[int] = []
        self._prompt = "Pick a robot that sees the landmarks, then start."

    @property
    def running(self) -> bool:
        return self._phase in ("waiting", "measuring")

    # -- the one entry point -----------------------------------------------------------------
    def handle(self, event: WizardEvent) -> list[WizardOutput]:
        """Take one event; returns what to do. ValueError for a user action that does not
        fit (names why); nothing changes then."""
        if isinstance(event, Start):
            return self._start(event)
        if isinstance(event, PoseSeen):
            self._poses[event.robot] = event.pose
            return []
        if isinstance(event, LedsSeen):
            self._on_leds(event)
            return self._step(event.t_ns)
        if isinstance(event, RadioSwitched):
            return self._on_radio(event)
        if isinstance(event, FrameSeen):
            self._poses[event.robot] = event.pose
            if self.running and event.robot == self._robot:
                self._on_frame(event)
            return self._step(event.t_ns)
        if isinstance(event, Tick):
            return self._step(event.t_ns)
        if isinstance(event, Confirm):
            return self._confirm(event)
        if isinstance(event, Skip):
            t = self._need_target("skip")
            self._skipped.append(t.candidate.landmark_id)
            return self._next(event.t_ns)
        if isinstance(event, SwitchAnyway):
            t = self._need_target("switch anyway")
            if t.known is None or not t.blockers:
                raise ValueError("nothing is waiting for a robot: no need to switch anyway")
            t.force = True
            return self._step(event.t_ns)
        if isinstance(event, Cancel):
            if not self.running:
                return []
            return self._finish("cancelled")
        raise TypeError(f"not a wizard event: {type(event).__name__}")

    def status(self) -> WizardStatus:
        t = self._target
        m = None if t is None else self._measurement(t)
        far = m is not None and m.plausibility.far
        return WizardStatus(
            phase=self._phase,
            robot=self._robot,
            index=self._index,
            total=len(self._queue),
            candidate=None if t is None else t.candidate,
            prompt=self._prompt,
            measurement=m,
            can_confirm=self.running and m is not None and not far,
            needs_accept_far=self.running and far,
            waiting_for=() if t is None else t.blockers,
            saved=tuple(self._saved),
            skipped=tuple(self._skipped),
        )

    # -- user actions --------------------------------------------------------------------------
    def _start(self, e: Start) -> list[WizardOutput]:
        if self.running:
            raise ValueError("the identification wizard is already running")
        if not e.queue:
            raise ValueError("nothing to identify: name landmark IDs or radio addresses")
        if e.robot not in e.robots:
            raise ValueError(f"unknown robot {e.robot!r}; robots: {', '.join(e.robots)}")
        for c in e.queue:
            if c.radio is None and c.landmark_id not in e.landmarks:
                raise ValueError(f"landmark {c.landmark_id} is not in the map")
        self._phase, self._robot, self._camera = "waiting", e.robot, e.camera
        self._queue, self._index = tuple(e.queue), 0
        self._landmarks = dict(e.landmarks)
        self._ceiling_z = e.ceiling_z
        self._saved, self._skipped = [], []
        # unmapped LEDs would be stray spots in every frame: new radios wait dark for their
        # turn (the first is measured at once: it starts lit)
        out: list[WizardOutput] = [SwitchRadio(c.radio, False) for c in e.queue[1:] if c.radio]
        self._begin(e.t_ns)
        return out + self._step(e.t_ns)

    def _confirm(self, e: Confirm) -> list[WizardOutput]:
        t = self._need_target("confirm")
        if e.position is not None:
            p = tuple(float(v) for v in e.position)
            if len(p) != 3 or not all(math.isfinite(v) for v in p):
                raise ValueError(f"position: expected three finite numbers (m), got {p}")
            pos = (p[0], p[1], p[2])
        else:
            m = self._measurement(t)
            if m is None:
                raise ValueError(
                    "nothing measured yet: wait for the measurement, type the position by "
                    "hand, or skip"
                )
            if m.plausibility.far and not e.accept_far:
                raise ValueError(
                    f"the measurement is far from the map ({m.plausibility.note}): "
                    "confirm with accept_far if the landmark really moved"
                )
            pos = m.position
        self._saved.append(t.candidate.landmark_id)
        out: list[WizardOutput] = [SaveLandmark(t.candidate, pos)]
        if t.candidate.radio is not None:  # a landmark now: the site switches it
            self._radio_on.pop(t.candidate.radio, None)
        return out + self._next(e.t_ns, saved_radio=t.candidate.radio is not None)

    def _need_target(self, action: str) -> _Target:
        if not self.running or self._target is None:
            raise ValueError(f"cannot {action}: the identification wizard is not running")
        return self._target

    # -- the queue -------------------------------------------------------------------------------
    def _begin(self, t_ns: int) -> None:
        c = self._queue[self._index]
        known = self._landmarks.get(c.landmark_id) if c.radio is None else None
        height = known.z if known is not None else self._ceiling_z
        # it starts lit (a landmark is, a new radio is asked to be: it was lit when found),
        # then it is darkened: a spot is measured from its second lit phase on
        assert self._camera is not None
        others = [(lm.x, lm.y) for lid, lm in self._landmarks.items() if lid != c.landmark_id]
        sampled = TargetSamples(self._camera, self.config, others)
        self._target = _Target(c, known, height, want_on=True, sampled=sampled, started_ns=t_ns)
        self._phase = "waiting"
        self._prompt = f"{self._what(c)}: starting"

    def _next(self, t_ns: int, *, saved_radio: bool = False) -> list[WizardOutput]:
        t = self._target
        out: list[WizardOutput] = []
        if t is not None and t.known is not None:
            out.append(SwitchLandmark(t.candidate.landmark_id, True))
        elif t is not None and t.candidate.radio is not None and not saved_radio:
            out.append(SwitchRadio(t.candidate.radio, False))
        self._index += 1
        if self._index >= len(self._queue):
            return out + self._finish("done", relit=True)
        self._begin(t_ns)
        return out + self._step(t_ns)

    def _finish(
        self, phase: Literal["done", "cancelled"], *, relit: bool = False
    ) -> list[WizardOutput]:
        t = self._target
        out: list[WizardOutput] = []
        if not relit and t is not None and t.known is not None:
            out.append(SwitchLandmark(t.candidate.landmark_id, True))
        # radios from discovery that were not saved are left lit, as before the start
        out += [
            SwitchRadio(c.radio, True)
            for c in self._queue
            if c.radio is not None and c.landmark_id not in self._saved
        ]
        self._phase, self._target = phase, None
        saved = ", ".join(map(str, self._saved)) or "none"
        skipped = ", ".join(map(str, self._skipped)) or "none"
        self._prompt = f"{phase}: saved {saved}, skipped {skipped}; LEDs restored"
        return [*out, Finished(phase, tuple(self._saved), tuple(self._skipped))]

    # -- LEDs --------------------------------------------------------------------------------------
    def _on_leds(self, e: LedsSeen) -> None:
        if self._leds and e.t_ns < self._leds[-1].t_ns:
            return  # stale
        self._leds.append(e)
        horizon = e.t_ns - round(self.config.keep_s * 1e9)
        while len(self._leds) >= 2 and self._leds[1].t_ns <= horizon:
            self._leds.popleft()

    def _leds_at(self, t_ns: int) -> LedsSeen | None:
        """The LED state in force at `t_ns`; the LEDs it switched less than `settle_s`
        before count as changing. None when unknown."""
        state = before = None
        for s in self._leds:
            if s.t_ns <= t_ns:
                state, before = s, state
        if state is None or t_ns - state.t_ns >= self.config.settle_s * 1e9:
            return state
        if before is None:
            return None
        recent = (state.lit ^ before.lit) | before.changing
        return LedsSeen(state.t_ns, state.lit, state.changing | recent)

    def _on_radio(self, e: RadioSwitched) -> list[WizardOutput]:
        t = self._target
        if e.error:
            if t is not None and t.candidate.radio == e.address and self.running:
                self._prompt = f"radio {e.address} did not switch its LED ({e.error}): skip it"
            return []
        self._radio_on[e.address] = (e.on, e.t_ns)
        return self._step(e.t_ns)

    def _target_on_at(self, t: _Target, t_ns: int, leds: LedsSeen) -> bool | None:
        """Whether the target's LED was (surely) lit at `t_ns`; None when unknown (it was
        being switched then, or confirmed too recently; a new radio: from asking for the
        state until its acknowledgement)."""
        settle = round(self.config.settle_s * 1e9)
        for since, until in t.unsure:
            if since <= t_ns and (until is None or t_ns < until + settle):
                return None
        if t.known is not None:
            lid = t.candidate.landmark_id
            return None if lid in leds.changing else lid in leds.lit
        radio = self._radio_on.get(t.candidate.radio or "")
        if radio is None or t_ns - radio[1] < settle:
            return None
        return radio[0]

    def _target_on_now(self, t: _Target) -> bool | None:
        if t.known is not None:
            if not self._leds:
                return None
            now = self._leds[-1]
            lid = t.candidate.landmark_id
            return None if lid in now.changing else lid in now.lit
        radio = self._radio_on.get(t.candidate.radio or "")
        return None if radio is None else radio[0]

    # -- robots' fixes -------------------------------------------------------------------------
    def _blockers(self, t: _Target) -> tuple[str, ...]:
        """Robots tracking with the target that would keep fewer than `min_fix_landmarks`
        other landmarks."""
        lid = t.candidate.landmark_id
        out = []
        for name, pose in sorted(self._poses.items()):
            used = set(pose.landmark_ids)
            short = len(used - {lid}) < self.config.min_fix_landmarks
            if pose.mode == "landmark" and lid in used and short:
                out.append(name)
        return tuple(out)

    # -- the cycle -------------------------------------------------------------------------------
    def _step(self, t_ns: int) -> list[WizardOutput]:
        t = self._target
        if not self.running or t is None:
            return []
        cfg = self.config
        out: list[WizardOutput] = []
        on_now = self._target_on_now(t)
        if on_now is not None and on_now == t.want_on and t.since_ns is None:
            t.since_ns = t_ns
            if t.unsure and t.unsure[-1][1] is None:
                t.unsure[-1] = (t.unsure[-1][0], t_ns)
        held_s = None if t.since_ns is None else (t_ns - t.since_ns) * 1e-9
        want_next = not t.want_on
        if held_s is not None and held_s >= (cfg.dark_s if not t.want_on else cfg.lit_s):
            if t.known is not None and not want_next and not t.force:
                blockers = self._blockers(t)
                if blockers:
                    t.blockers = blockers
                    t.waiting_since_ns = t.waiting_since_ns or t_ns
                    self._phase = "waiting"
                    self._prompt = waiting_prompt(
                        self._what(t.candidate),
                        t.candidate.landmark_id,
                        blockers,
                        (t_ns - t.waiting_since_ns) * 1e-9,
                        min_fix_landmarks=cfg.min_fix_landmarks,
                        wait_fix_s=cfg.wait_fix_s,
                    )
                    return out
            t.blockers, t.waiting_since_ns = (), None
            t.want_on, t.since_ns, t.asked_ns = want_next, None, None
            self._phase = "measuring"
        if t.since_ns is None and (
            t.asked_ns is None or t_ns - t.asked_ns >= cfg.resend_s * 1e9
        ):  # ask for the wanted state (again: something may have replaced it)
            if t.asked_ns is None and t.known is None:
                t.unsure.append((t_ns, None))
            t.asked_ns = t_ns
            if t.known is not None:
                out.append(SwitchLandmark(t.candidate.landmark_id, t.want_on))
            elif t.candidate.radio is not None:
                out.append(SwitchRadio(t.candidate.radio, t.want_on))
        if self._phase == "measuring":
            self._prompt = self._measuring_prompt(t, t_ns)
        elif not t.blockers and (t_ns - t.started_ns) * 1e-9 >= cfg.no_spot_s:
            self._prompt = never_switched_prompt(self._what(t.candidate), t.want_on)
        return out

    def _on_frame(self, e: FrameSeen) -> None:
        t = self._target
        assert t is not None and self._camera is not None
        cfg = self.config
        pose = e.pose
        cov = np.asarray(pose.covariance, dtype=np.float64)
        sigma = math.sqrt(max(0.0, float(cov[0, 0] + cov[1, 1])))
        if pose.mode != "landmark" or sigma > cfg.max_sigma_m:
            return
        leds = self._leds_at(e.t_ns)
        on = None if leds is None else self._target_on_at(t, e.t_ns, leds)
        if leds is None or on is None:
            return
        pts = place_spots(self._camera, (pose.x, pose.y, pose.theta), e.pixels, t.height)
        target = {t.candidate.landmark_id}
        px = np.asarray(e.pixels, dtype=np.float64).reshape(-1, 2)
        xyt = (pose.x, pose.y, pose.theta)
        frame = PlacedFrame(e.t_ns, leds.lit - target, on, px, pts, xyt, leds.changing - target)
        t.sampled.add(frame)
        t.unsure = [u for u in t.unsure if u[1] is None or u[1] >= t.sampled.horizon_ns]

    def _measurement(self, t: _Target) -> Measurement | None:
        a, s = t.sampled.agreed, t.sampled
        if a is None:
            return None
        others = [lm for lid, lm in self._landmarks.items() if lid != t.candidate.landmark_id]
        plaus = plausibility(a.position, t.known, others, far_m=self.config.far_m)
        return Measurement(a.position, a.count, a.spread_m, plaus, s.pixel, s.frame_ns)

    # -- prompts (worded in `commissioning.wizard_prompts`) -------------------------------------
    def _what(self, c: Candidate) -> str:
        return what(c, self._index, len(self._queue))

    def _measuring_prompt(self, t: _Target, t_ns: int) -> str:
        late = (t_ns - t.started_ns) * 1e-9 >= self.config.no_spot_s
        count = len(t.sampled.points)
        no_spot = None if count or not late else no_spot_prompt(self._no_spot(t))
        return measuring_prompt(self._what(t.candidate), self._measurement(t), count, no_spot)

    def _no_spot(self, t: _Target) -> NoSpot:
        pose = self._poses.get(self._robot)
        in_view = False
        if pose is not None and t.known is not None and self._camera is not None:
            lm = t.known
            p = np.array([[lm.x, lm.y, lm.z]])
            seen = expected_in_view(
                self._camera, (pose.x, pose.y, pose.theta), p, margin_px=self.config.margin_px
            )
            in_view = bool(seen[0])
        return NoSpot(
            robot=self._robot,
            pose=pose,
            known=t.known,
            radio=t.candidate.radio,
            in_view=in_view,
            reflections=t.sampled.ambiguous > t.sampled.pairs // 2,
            flickering=t.sampled.flickering,
            min_cycles=self.config.min_cycles,
        )


def landmarks_from(records: Sequence[MapLandmark]) -> dict[int, MapLandmark]:
    """The map by ID."""
    return {lm.id: lm for lm in records}


# the messages live in `commissioning.wizard_messages`; importers take them from here too
__all__ = [
    "Cancel",
    "Confirm",
    "Finished",
    "FrameSeen",
    "IdentificationWizard",
    "LedsSeen",
    "Measurement",
    "Phase",
    "PoseSeen",
    "RadioSwitched",
    "SaveLandmark",
    "Skip",
    "Start",
    "SwitchAnyway",
    "SwitchLandmark",
    "SwitchRadio",
    "Tick",
    "WizardConfig",
    "WizardEvent",
    "WizardOutput",
    "WizardStatus",
    "landmarks_from",
]
