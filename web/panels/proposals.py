"""Map proposals: the landmark changes the robots' views call for (`survey.upkeep`), with
Accept and Reject. A thin client of the server's `MapUpkeepService`, the same one the REST
API drives (`GET /commissioning/map-proposals`, `POST .../accept`, `POST .../reject`):
accepting is an ordinary map edit (audited with this browser's user, undoable in the Undo /
redo panel). Admin only.
"""

from __future__ import annotations

from collections.abc import Callable

import viser

from live.upkeep_service import MapUpkeepService, UpkeepStatus
from web.roles import Session

NONE = "(no proposal)"


def proposal_lines(st: UpkeepStatus) -> list[str]:
    """One markdown line per proposal in plain words, moved ones first: "moved 4.8 cm"
    (beyond what the map said it knew), else "small correction of 3 mm" (within it)."""
    out = []
    for v in st.proposals:
        p = v.proposal
        lock = " (**locked**: unlock it to accept)" if v.locked else ""
        x, y, _ = p.proposed
        what = (
            f"**{p.landmark_id}** moved {100 * p.shift_m:.1f} cm"
            if p.kind == "moved"
            else f"{p.landmark_id}: small correction of {1000 * p.shift_m:.0f} mm"
        )
        out.append(
            f"- {what}{lock}: the robots see it at ({x:.2f}, {y:.2f}) m, give or take "
            f"{1000 * p.sigma_m:.0f} mm, from {p.views} views"
        )
    return out


def choice_label(st: UpkeepStatus, landmark_id: int) -> str:
    v = next(v for v in st.proposals if v.proposal.landmark_id == landmark_id)
    return f"{landmark_id} ({v.proposal.kind}{', locked' if v.locked else ''})"


class ProposalsPanel:
    """The proposals list and the Accept / Reject buttons of one admin's browser."""

    def __init__(
        self,
        gui: viser.GuiApi,
        upkeep: MapUpkeepService,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        self.upkeep, self.session, self.notify = upkeep, session, notify
        with gui.add_folder("Map proposals (robots' views)", expand_by_default=False):
            self.gui_list = gui.add_markdown("")
            self.gui_choice = gui.add_dropdown("Landmark", (NONE,))
            self.gui_accept = gui.add_button("Accept (move it in the map)", disabled=True)
            self.gui_reject = gui.add_button("Reject (gather evidence afresh)", disabled=True)
            self.gui_accept_all = gui.add_button("Accept all unlocked", disabled=True)
        self.gui_accept.on_click(lambda _: self._do(self.accept, self.chosen()))
        self.gui_reject.on_click(lambda _: self._do(self.reject, self.chosen()))
        self.gui_accept_all.on_click(lambda _: self._do(self.accept, None))
        self.gui_choice.on_update(lambda _: self._picked_by_hand())
        self._labels: dict[str, int] = {}
        self._picked: str | None = None  # what this user chose (kept while it is listed)
        self.refresh()

    def _picked_by_hand(self) -> None:
        value = str(self.gui_choice.value)
        if value in self._labels and value != next(iter(self._labels), None):
            self._picked = value

    def chosen(self) -> int | None:
        """The landmark of the dropdown's proposal, or None."""
        return self._labels.get(str(self.gui_choice.value))

    def refresh(self) -> None:
        """Show the proposals now (call at a few hertz)."""
        st = self.upkeep.status()
        lines = proposal_lines(st)
        head = f"{st.frames} frames gave evidence on {st.landmarks_seen} landmarks; " + (
            f"{len(lines)} proposals:" if lines else "no change proposed."
        )
        text = "\n".join([head, *lines])
        if self.gui_list.content != text:
            self.gui_list.content = text
        labels = {
            choice_label(st, v.proposal.landmark_id): v.proposal.landmark_id for v in st.proposals
        }
        if labels != self._labels:
            self._labels = labels
            self.gui_choice.options = tuple(labels) or (NONE,)
            # the first (moved ones first) unless this user picked one still listed: kept
            # from an earlier list, a 3 mm refinement stayed chosen over a 5 cm move
            keep = self._picked if self._picked in labels else None
            first = next(iter(labels), NONE)
            self.gui_choice.value = keep or first  # type: ignore[misc]
        has = bool(labels)
        self.gui_accept.disabled = self.gui_reject.disabled = not has
        self.gui_accept_all.disabled = not any(not v.locked for v in st.proposals)

    @staticmethod
    def _do(action: Callable[[int | None], list[int]], landmark_id: int | None) -> None:
        action(landmark_id)

    def accept(self, landmark_id: int | None) -> list[int]:
        """Accept one proposal (None: every unlocked one), as `POST .../accept`."""
        ids = None if landmark_id is None else [landmark_id]
        try:
            done = self.upkeep.accept(ids, actor=self.session.actor)
        except (ValueError, KeyError) as exc:  # ConflictError is a ValueError
            self.notify("Refused", str(exc))
            return []
        self.notify("Map proposals", f"accepted: {', '.join(map(str, done)) or 'none'}")
        self.refresh()
        return done

    def reject(self, landmark_id: int | None) -> list[int]:
        """Reject one proposal, as `POST .../reject`."""
        try:
            done = self.upkeep.reject(
                [] if landmark_id is None else [landmark_id], actor=self.session.actor
            )
        except ValueError as exc:
            self.notify("Refused", str(exc))
            return []
        self.notify("Map proposals", f"rejected: {', '.join(map(str, done))}")
        self.refresh()
        return done
