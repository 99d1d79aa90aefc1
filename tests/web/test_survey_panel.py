"""The survey panel (`web.panels.survey`) on an in-memory site: what it draws, says and does."""

from __future__ import annotations

import math

import numpy as np
import pytest
import viser

from live.survey.service import Proposal, SurveyStatus
from tests.web.memsite import grid_site
from web.panels.survey import SurveyPanel, ellipse_ring, progress_text, survey_segments
from web.roles import Session


def prop(lid: int, state: str, sigma: float, **kw: object) -> Proposal:
    lm = (float(lid - 10), 0.0)  # the grid's first row: 10, 11, 12, 13 at x = 0 .. 3
    fields: dict[str, object] = dict(
        landmark_id=lid, x=lm[0] + 0.01, y=lm[1], z=2.5, sigma_m=sigma, moved_m=0.01, views=5,
        rms_px=0.3, anchor=state == "anchor", flags=(), ellipse=(sigma, sigma / 2, 0.0),
        state=state,
    )  # fmt: skip
    fields.update(kw)
    return Proposal(**fields)  # type: ignore[arg-type]


def test_ellipse_ring_is_the_scaled_ellipse_with_a_floor() -> None:
    ring = ellipse_ring((1.0, 2.0), (0.02, 0.01, math.pi / 2), 20.0, n=4)
    # major 0.4 m along +y, minor 0.2 m along -x at a quarter turn
    np.testing.assert_allclose(ring[0], [1.0, 2.4], atol=1e-12)
    np.testing.assert_allclose(ring[1], [0.8, 2.0], atol=1e-12)
    tiny = ellipse_ring((0.0, 0.0), (1e-4, 1e-4, 0.0), 1.0, n=8)
    assert np.hypot(*tiny.T).max() == pytest.approx(0.15)  # never drawn smaller


def test_segments_by_state_and_the_progress_line() -> None:
    site = grid_site()
    st = SurveyStatus(
        "driving", "r1", blinks=42, drive_s=12.4, estimates=2,
        proposals=(prop(10, "anchor", 0.0), prop(11, "converging", 0.012),
                   prop(12, "flagged", 0.004, flags=("moved, or radios swapped?",))),
    )  # fmt: skip
    segs = survey_segments(st, site.landmarks(), 20.0)
    assert len(segs["converging"]) == 24 and len(segs["anchor"]) == 24
    assert len(segs["converged"]) == 0
    assert len(segs["unseen"]) == 12 * (12 - 3)  # every other landmark of the grid
    assert np.all(segs["converging"][..., 2] == 2.5)
    assert np.ptp(segs["converging"][..., 0]) == pytest.approx(2 * 0.24, rel=1e-3)
    text = progress_text(st, 12)
    assert "3 of 12 landmarks placed, 0 converged (1-sigma <= 5 mm), 1 flagged" in text
    assert "robot time 12 s; 42 blinks" in text


def test_panel_starts_accepts_one_landmark_and_draws_the_route() -> None:
    site = grid_site()
    server = viser.ViserServer("127.0.0.1", 0, verbose=False)
    notes: list[str] = []
    try:
        panel = SurveyPanel(server, site, Session("admin", "viewer:key:1"),
                            lambda t, b: notes.append(b))  # fmt: skip
        assert panel.gui_accept_one.disabled and not panel.gui_start.disabled
        panel.gui_robot.value = "r1"  # type: ignore[misc]
        panel._run(panel._start)
        assert site.survey.state == "driving" and panel.gui_start.disabled
        site.survey = SurveyStatus(
            "driving", "r1", proposals=(prop(10, "anchor", 0.0), prop(11, "converging", 0.01)),
            route=((2.0, 2.0), (3.0, 0.0)),
        )  # fmt: skip
        panel.refresh()
        assert set(panel._nodes) == {"anchor", "converging", "unseen", "route"}
        route = panel._nodes["route"].points
        np.testing.assert_allclose(route[-1, 1], [3.0, 0.0, 0.03], atol=1e-6)  # ends there
        assert not panel.gui_accept_one.disabled
        panel.gui_id.value = 7  # type: ignore[misc]
        panel._run(panel._accept_one)
        assert notes and "not surveyed" in notes[-1]  # the refusal is shown, nothing written
        assert site.map[11].x == 1.0
        panel.gui_id.value = 11  # type: ignore[misc]
        panel._run(panel._accept_one)
        assert site.map[11].x == pytest.approx(1.01) and site.survey.accepted == (11,)
        assert "accepted: 11" in panel.gui_progress.content
        panel._run(lambda: site.survey_cancel(actor="t"))
        assert set(panel._nodes) == set()  # nothing drawn once idle
    finally:
        server.stop()
