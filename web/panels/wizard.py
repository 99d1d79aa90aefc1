"""The identification wizard's GUI: robot, what to identify (landmark IDs and radio
addresses; "Suggest" fills in the doubted landmarks and the new radios a discovery finds),
the camera frame with its detections, the proposed position, and confirm / retry / skip /
type by hand / cancel."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

import cv2
import numpy as np
import numpy.typing as npt
import viser

from web.candidates import landmark_id_for_radio
from web.measure import Measurement
from web.roles import Session
from web.services import CameraView, Candidate, ViewerSite
from web.wizard import IdentificationWizard, WizardState


def annotated_frame(
    view: CameraView, chosen: npt.ArrayLike | None, *, width_px: int = 320
) -> npt.NDArray[np.uint8]:
    """The frame as RGB, scaled to `width_px`, spots circled (the chosen one in green)."""
    img = cv2.cvtColor(view.image, cv2.COLOR_GRAY2RGB)
    scale = width_px / img.shape[1]
    img = cv2.resize(img, (width_px, round(img.shape[0] * scale)), interpolation=cv2.INTER_AREA)
    for p in np.asarray(view.spots).reshape(-1, 2):
        cv2.circle(img, (round(p[0] * scale), round(p[1] * scale)), 7, (230, 60, 60), 1)
    if chosen is not None:
        c = np.asarray(chosen).reshape(2)
        cv2.circle(img, (round(c[0] * scale), round(c[1] * scale)), 10, (60, 230, 60), 2)
    return np.asarray(img, dtype=np.uint8)


_RADIO = re.compile(r"^[0-9A-Fa-f]{16}$")


def parse_targets(text: str) -> list[int | str]:
    """Landmark IDs and radio addresses (16 hex digits, upper-cased) from
    "3, 5 0013A20041000105": ValueError names a bad token."""
    out: list[int | str] = []
    for tok in text.replace(",", " ").split():
        if _RADIO.match(tok):
            out.append(tok.upper())
            continue
        try:
            out.append(int(tok))
        except ValueError:
            raise ValueError(
                f"landmarks to identify: {tok!r} is neither a landmark ID nor a radio address "
                "(16 hex digits)"
            ) from None
    return out


def candidates_for(
    targets: Sequence[int | str], suggested: Sequence[Candidate], taken_ids: set[int]
) -> list[Candidate]:
    """The wizard's queue for typed targets: a suggested candidate when it matches (its
    reason, a new radio's ID), else a landmark of the map or a new radio with a free ID."""
    by_id = {c.landmark_id: c for c in suggested if c.radio is None}
    by_radio = {c.radio: c for c in suggested if c.radio is not None}
    taken = set(taken_ids) | {c.landmark_id for c in suggested}
    out = []
    for t in targets:
        if isinstance(t, str):
            out.append(by_radio.get(t) or Candidate(landmark_id_for_radio("", taken), t))
        else:
            out.append(by_id.get(t) or Candidate(t))
    return out


def targets_text(candidates: Sequence[Candidate]) -> str:
    """The text field's content for candidates: IDs and radio addresses."""
    return " ".join(c.radio if c.radio is not None else str(c.landmark_id) for c in candidates)


def suggestions_text(candidates: Sequence[Candidate]) -> str:
    """Markdown list of suggested candidates with the reason for each."""
    if not candidates:
        return "_nothing doubted, no new radios_"
    return "\n".join(
        f"- **{c.landmark_id}**{' (new)' if c.is_new else ''}: {c.reason}" for c in candidates
    )


def status_text(state: WizardState) -> str:
    """What the wizard is doing, in markdown."""
    if state.phase == "idle":
        return "Pick a robot that sees the landmarks, then start."
    if state.phase in ("done", "cancelled"):
        return (
            f"**{state.phase}**: saved {state.saved or 'none'}, skipped {state.skipped or 'none'};"
            " LEDs restored."
        )
    m = state.measurement
    c = state.candidate
    what = f"Landmark **{state.current}**"
    if c is not None and c.radio is not None:
        what = f"New radio `{c.radio}` (to be landmark **{c.landmark_id}**)"
    head = f"{what} ({state.index + 1} of {len(state.queue)}), lit alone."
    return head if m is None else f"{head}\n\n{m.message}"


class WizardPanel:
    """One admin browser's view of the (site-wide) wizard."""

    def __init__(
        self,
        gui: viser.GuiApi,
        site: ViewerSite,
        wizard: IdentificationWizard,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        self.site, self.wizard, self.session, self.notify = site, wizard, session, notify
        names = [r.name for r in site.robots()] or ["-"]
        with gui.add_folder("Identify landmarks"):
            self.gui_robot = gui.add_dropdown("Camera of", names)
            self.gui_ids = gui.add_text("Landmark IDs", "")
            self.gui_suggest = gui.add_button("Suggest landmarks to identify")
            self.gui_suggested = gui.add_markdown("")
            self.gui_start = gui.add_button("Start identification")
            self.gui_progress = gui.add_progress_bar(0.0)
            self.gui_status = gui.add_markdown(status_text(wizard.state))
            self.gui_frame = gui.add_image(np.zeros((240, 320, 3), np.uint8), label="camera")
            self.gui_confirm = gui.add_button("Confirm position")
            self.gui_retry = gui.add_button("Retry")
            self.gui_skip = gui.add_button("Skip")
            self.gui_manual = gui.add_vector3("Position by hand (m)", (0.0, 0.0, 2.5), step=0.01)
            self.gui_save_manual = gui.add_button("Save position by hand")
            self.gui_cancel = gui.add_button("Cancel identification", color="red")
        self.gui_suggest.on_click(lambda _: self._suggest())
        self.gui_start.on_click(lambda _: self._run(self._start))
        self.gui_confirm.on_click(
            lambda _: self._run(lambda: self.wizard.confirm(actor=self.actor))
        )
        self.gui_retry.on_click(lambda _: self._run(lambda: self.wizard.retry(actor=self.actor)))
        self.gui_skip.on_click(lambda _: self._run(lambda: self.wizard.skip(actor=self.actor)))
        self.gui_save_manual.on_click(
            lambda _: self._run(
                lambda: self.wizard.confirm(actor=self.actor, position=self.gui_manual.value)
            )
        )
        self.gui_cancel.on_click(lambda _: self._run(lambda: self.wizard.cancel(actor=self.actor)))
        self._shown: tuple[str, int, int | None] | None = None
        self._suggested: list[Candidate] = []
        self.refresh()

    @property
    def actor(self) -> str:
        return self.session.actor

    def _suggest(self) -> None:
        try:
            found = self.site.to_identify(discover=True)
        except ValueError as exc:
            self.notify("Discovery failed", f"{exc}; showing doubted landmarks only")
            found = self.site.to_identify()
        self._suggested = found
        self.gui_suggested.content = suggestions_text(found)
        self.gui_ids.value = targets_text(found)  # type: ignore[misc]

    def _start(self) -> Measurement | None:
        targets = parse_targets(self.gui_ids.value)
        if not targets:
            return self.wizard.start(self.gui_robot.value, self._suggested, actor=self.actor)
        taken = {lm.id for lm in self.site.landmarks()}
        queue = candidates_for(targets, self._suggested, taken)
        return self.wizard.start(self.gui_robot.value, queue, actor=self.actor)

    def _run(self, step: Callable[[], Measurement | None]) -> None:
        try:
            m = step()
        except (KeyError, ValueError, TimeoutError) as exc:
            self.notify("Identification", str(exc))
        else:
            if m is not None and m.position is not None:
                p = m.position
                self.gui_manual.value = (float(p[0]), float(p[1]), float(p[2]))  # type: ignore[misc]
        self.refresh()

    def refresh(self) -> None:
        """Show the wizard's state (cheap when unchanged)."""
        st = self.wizard.state
        m = st.measurement
        key = (st.phase, st.index, None if m is None or m.view is None else m.view.t_ns)
        if key == self._shown:
            return
        self._shown = key
        done = 100.0 if st.phase == "done" else 0.0
        self.gui_progress.value = st.progress if st.phase == "measured" else done  # type: ignore[misc]
        self.gui_status.content = status_text(st)
        running = st.phase == "measured"
        for b in (self.gui_confirm, self.gui_retry, self.gui_skip, self.gui_save_manual,
                  self.gui_cancel):  # fmt: skip
            b.disabled = not running
        self.gui_start.disabled = running
        if m is not None and m.view is not None:
            self.gui_frame.image = annotated_frame(m.view, m.spot)
