"""The identification wizard's GUI, a thin client of the server's wizard (the same one
`/api/v1/commissioning/wizard` drives): robot, what to identify (landmark IDs and radio
addresses; "Suggest" fills in the doubted landmarks and the new radios a discovery finds),
the camera frame with the target's spot, what the wizard says (what it waits for, what to
move), the agreed position, and confirm (only for a plausible measurement that agrees over
several frames; one far from the map needs "accept far" ticked) / switch anyway / skip /
type by hand / cancel."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

import cv2
import numpy as np
import numpy.typing as npt
import viser

from commissioning.candidates import landmark_id_for_radio
from commissioning.wizard import WizardStatus
from web.roles import Session
from web.services import CameraView, Candidate, ViewerSite


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


def status_text(state: WizardStatus) -> str:
    """What the wizard is doing, in markdown."""
    if state.phase == "idle":
        return "Pick a robot that sees the landmarks, then start."
    text = state.prompt
    m = state.measurement
    if state.phase in ("waiting", "measuring") and m is not None and m.plausibility.far:
        text += "\n\n**Far from the map**: tick *accept far* to confirm it anyway."
    return text


class WizardPanel:
    """One admin browser's view of the (site-wide) wizard."""

    def __init__(
        self,
        gui: viser.GuiApi,
        site: ViewerSite,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        self.site, self.session, self.notify = site, session, notify
        names = [r.name for r in site.robots()] or ["-"]
        with gui.add_folder("Identify landmarks"):
            self.gui_robot = gui.add_dropdown("Camera of", names)
            self.gui_ids = gui.add_text("Landmark IDs", "")
            self.gui_suggest = gui.add_button("Suggest landmarks to identify")
            self.gui_suggested = gui.add_markdown("")
            self.gui_start = gui.add_button("Start identification")
            self.gui_progress = gui.add_progress_bar(0.0)
            self.gui_status = gui.add_markdown(status_text(site.wizard_status()))
            self.gui_frame = gui.add_image(np.zeros((240, 320, 3), np.uint8), label="camera")
            self.gui_accept_far = gui.add_checkbox("Accept far", False, disabled=True)
            self.gui_confirm = gui.add_button("Confirm position", disabled=True)
            self.gui_anyway = gui.add_button("Switch anyway", disabled=True)
            self.gui_skip = gui.add_button("Skip", disabled=True)
            self.gui_manual = gui.add_vector3("Position by hand (m)", (0.0, 0.0, 2.5), step=0.01)
            self.gui_save_manual = gui.add_button("Save position by hand", disabled=True)
            self.gui_cancel = gui.add_button("Cancel identification", color="red", disabled=True)
        self.gui_suggest.on_click(lambda _: self._suggest())
        self.gui_start.on_click(lambda _: self._run(self._start))
        self.gui_confirm.on_click(
            lambda _: self._run(
                lambda: self.site.wizard_confirm(
                    actor=self.actor, accept_far=bool(self.gui_accept_far.value)
                )
            )
        )
        self.gui_anyway.on_click(
            lambda _: self._run(lambda: self.site.wizard_switch_anyway(actor=self.actor))
        )
        self.gui_skip.on_click(lambda _: self._run(lambda: self.site.wizard_skip(actor=self.actor)))
        self.gui_save_manual.on_click(lambda _: self._run(self._save_manual))
        self.gui_cancel.on_click(
            lambda _: self._run(lambda: self.site.wizard_cancel(actor=self.actor))
        )
        self.gui_accept_far.on_update(lambda _: self.refresh(force=True))
        self._shown: tuple[object, ...] | None = None
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

    def _start(self) -> None:
        targets = parse_targets(self.gui_ids.value)
        if not targets:
            self.site.wizard_start(self.gui_robot.value, self._suggested, actor=self.actor)
            return
        taken = {lm.id for lm in self.site.landmarks()}
        queue = candidates_for(targets, self._suggested, taken)
        self.site.wizard_start(self.gui_robot.value, queue, actor=self.actor)

    def _save_manual(self) -> None:
        x, y, z = (float(v) for v in self.gui_manual.value)
        self.site.wizard_confirm(actor=self.actor, position=(x, y, z))

    def _run(self, step: Callable[[], None]) -> None:
        try:
            step()
        except (KeyError, ValueError, RuntimeError, TimeoutError) as exc:
            self.notify("Identification", str(exc))
        self.refresh(force=True)

    def refresh(self, *, force: bool = False) -> None:
        """Show the wizard's state (cheap when unchanged)."""
        st = self.site.wizard_status()
        m = st.measurement
        key = (
            st.phase,
            st.index,
            st.prompt,
            None if m is None else m.position,
            st.can_confirm,
            st.needs_accept_far,
        )
        if key == self._shown and not force:
            return
        self._shown = key
        running = st.phase in ("waiting", "measuring")
        done = 100.0 if st.phase == "done" else 0.0
        progress = 100.0 * st.index / st.total if running and st.total else done
        self.gui_progress.value = progress  # type: ignore[misc]
        self.gui_status.content = status_text(st)
        far_ok = st.needs_accept_far and bool(self.gui_accept_far.value)
        self.gui_confirm.disabled = not (st.can_confirm or far_ok)
        self.gui_accept_far.disabled = not st.needs_accept_far
        if not st.needs_accept_far and self.gui_accept_far.value:
            self.gui_accept_far.value = False  # type: ignore[misc]  # never carried over
        self.gui_anyway.disabled = not (running and bool(st.waiting_for))
        for b in (self.gui_skip, self.gui_save_manual, self.gui_cancel):
            b.disabled = not running
        self.gui_start.disabled = running
        if running and m is not None:
            x, y, z = m.position
            self.gui_manual.value = (x, y, z)  # type: ignore[misc]
        if running:
            view = self.site.camera_view(st.robot)
            if view is not None:
                self.gui_frame.image = annotated_frame(view, None if m is None else m.pixel)
