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
    """One markdown line per proposal, moved ones first."""
    out = []
    for v in st.proposals:
        p = v.proposal
        lock = " **locked**" if v.locked else ""
        x, y, z = p.proposed
        out.append(
            f"- **{p.landmark_id}** {p.kind}{lock}: {1000 * p.shift_m:.1f} mm to "
            f"({x:.3f}, {y:.3f}, {z:.3f}) +- {1000 * p.sigma_m:.1f} mm, "
            f"{p.views} views, chi2 {p.statistic:.1f}"
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
        self._labels: dict[str, int] = {}
        self.refresh()

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
        labels = {choice_label(st, v.proposal.landmark_id): v.proposal.landmark_id
                  for v in st.proposals}  # fmt: skip
        if labels != self._labels:
            self._labels = labels
            current = str(self.gui_choice.value)
            self.gui_choice.options = tuple(labels) or (NONE,)
            if current in labels:
                self.gui_choice.value = current  # type: ignore[misc]
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
            done = self.upkeep.reject([] if landmark_id is None else [landmark_id],
                                      actor=self.session.actor)  # fmt: skip
        except ValueError as exc:
            self.notify("Refused", str(exc))
            return []
        self.notify("Map proposals", f"rejected: {', '.join(map(str, done))}")
        self.refresh()
        return done
