from __future__ import annotations

import dataclasses
from dataclasses import replace

import numpy as np
import pytest
import viser

from commissioning.types import MapLandmark
from commissioning.wizard import Confirm, IdentificationWizard, Skip, Start
from sim.cameras import wide_angle_camera
from tests.web.memsite import grid_site
from web.battery_table import battery_table
from web.panels.commission import nearest_landmark
from web.panels.monitor import (
    UncertaintyHistory,
    events_text,
    fix_age_s,
    position_sigma_m,
    robots_table,
)
from web.panels.wizard import (
    annotated_frame,
    candidates_for,
    parse_targets,
    status_text,
    suggestions_text,
    targets_text,
)
from web.services import CameraView, Candidate, LandmarkState


def test_robots_table_shows_mode_error_and_fix_age() -> None:
    site = grid_site()
    robots = site.robots()
    sigma = position_sigma_m(robots[0])
    assert sigma == pytest.approx(np.sqrt(5e-4))
    assert fix_age_s(robots[0]) == pytest.approx(0.0)
    table = robots_table(robots)
    assert "| r1 | landmarks | 2.2 cm | - | 0.0 s ago | - |" in table
    assert table.startswith("| robot | mode | error (1 sigma) | quality | last fix | why no fix |")
    assert table.count("\n") == 3
    dark = dataclasses.replace(
        robots[0], mode="dead_reckoning", quality=0.61,
        reason_text="the 2 landmark(s) in view are switched off by the LED schedule",
    )  # fmt: skip
    assert robots_table([dark]).splitlines()[2] == (
        "| r1 | dead reckoning | 2.2 cm | 0.61 | 0.0 s ago | the 2 landmark(s) in view are "
        "switched off by the LED schedule |"
    )


def test_batteries_low_first_unknown_last_with_the_schedule_and_the_model() -> None:
    lms = [
        LandmarkState(1, 0, 0, 2.5, supply_mv=3000, percent=80.0, days_left=300.0,
                      lit=True, lit_reason="view r1", duty=0.2, model_days=90.0),
        LandmarkState(2, 0, 0, 2.5),
        LandmarkState(3, 0, 0, 2.5, supply_mv=2300, percent=18.0, days_left=12.0,
                      reachable=False, duty=0.5, model_days=4.0, low=True),
        LandmarkState(4, 0, 0, 2.5, supply_mv=2900, duty=0.0, model_days=400.0),
    ]  # fmt: skip
    rows = battery_table(lms).splitlines()[2:]
    assert [r.split("|")[1].strip() for r in rows] == ["3 **LOW** (unreachable)", "1", "4", "2"]
    assert rows[0] == "| 3 **LOW** (unreachable) | 2.30 | 4 (12) | 50% | off | dark |"
    assert rows[1] == "| 1 | 3.00 | 90 (300) | 20% | on | view r1 |"
    by_volts = battery_table(lms, "volts").splitlines()[2:]
    assert [r.split("|")[1].strip()[0] for r in by_volts] == ["3", "4", "1", "2"]
    by_duty = battery_table(lms, "duty").splitlines()[2:]
    assert [r.split("|")[1].strip()[0] for r in by_duty] == ["3", "1", "2", "4"]


def test_uncertainty_history_series_ends_at_zero() -> None:
    h = UncertaintyHistory(maxlen=3)
    site = grid_site()
    for _ in range(5):
        h.add(site.robots())
    t, e = h.series("r1")
    assert len(t) == 3 and t[-1] == 0.0 and np.all(t <= 0)
    np.testing.assert_allclose(e, 100 * np.sqrt(5e-4))
    assert len(h.series("nobody")[0]) == 0


def test_parse_targets_and_status() -> None:
    assert parse_targets("3, 5 7 0013a20041000105") == [3, 5, 7, "0013A20041000105"]
    with pytest.raises(ValueError, match="'x' is neither"):
        parse_targets("3 x")
    with pytest.raises(ValueError, match="'0013A2004100010' is neither"):
        parse_targets("0013A2004100010")  # 15 hex digits
    wiz = IdentificationWizard()
    lms = {3: MapLandmark(3, 0.0, 0.0, 2.5), 5: MapLandmark(5, 1.0, 0.0, 2.5)}
    new = Candidate(109, "0013A2004100006D", "new radio")
    cam = wide_angle_camera("pinhole")
    wiz.handle(Start(0, "r1", cam, (Candidate(3), Candidate(5), new), lms, 2.5, ("r1",)))
    wiz.handle(Confirm(1, (0.1, 0.0, 2.5)))
    wiz.handle(Skip(2))
    assert status_text(wiz.status()).startswith(
        "New radio 0013A2004100006D (to be landmark 109) (3 of 3)"
    )
    wiz.handle(Skip(3))
    assert "done: saved 3, skipped 5, 109; LEDs restored" in status_text(wiz.status())


def test_typed_targets_become_candidates() -> None:
    suggested = [Candidate(12, None, "doubted: x"), Candidate(40, "0013A20041000028", "new")]
    assert targets_text(suggested) == "12 0013A20041000028"
    assert suggestions_text(suggested) == "- **12**: doubted: x\n- **40** (new): new"
    typed = parse_targets("0013A20041000028 12 13 0013A200410000FF")
    queue = candidates_for(typed, suggested, taken_ids={12, 13, 39})
    assert queue == [
        suggested[1],
        suggested[0],
        Candidate(13),
        Candidate(41, "0013A200410000FF"),  # a free ID above the map's and the suggestions'
    ]


def test_nearest_landmark_within_radius() -> None:
    lms = grid_site().landmarks()
    hit = nearest_landmark(lms, np.array([1.1, 0.95, 2.5]), 0.25)
    assert hit is not None and hit.id == 15
    assert nearest_landmark(lms, np.array([1.5, 0.5, 2.5]), 0.25) is None


def test_annotated_frame_circles_spots() -> None:
    img = np.zeros((480, 640), np.uint8)
    view = CameraView(0, img, np.array([[320.0, 240.0], [100.0, 100.0]]))
    out = annotated_frame(view, view.spots[0], width_px=320)
    assert out.shape == (240, 320, 3)
    assert out[120, 170, 1] > 200  # green ring of radius 10 around (160, 120)
    assert out[50, 57, 0] > 200  # red ring of radius 7 around (50, 50)


def test_error_column_says_nothing_while_a_robot_identifies() -> None:
    from web.panels.monitor import error_text

    rb = grid_site().robots()[0]
    assert error_text(rb) == "2.2 cm"
    assert error_text(replace(rb, mode="identifying")) == "-"  # its covariance reads 0
    assert error_text(replace(rb, mode="lost")) == "-"
    assert error_text(replace(rb, pose=None)) == "-"


def test_events_are_in_local_time_with_a_zone_and_runs_are_folded() -> None:
    import os
    import time as _time
    from datetime import datetime

    from web.panels.monitor import local_time_text
    from web.services import EventLine

    old = os.environ.get("TZ")
    os.environ["TZ"] = "Europe/Berlin"
    _time.tzset()
    try:
        # naive times are UTC (as stored): 20:00 UTC is 21:00 in Berlin in winter
        assert local_time_text(datetime(2026, 12, 1, 20, 0, 0)) == "2026-12-01 21:00:00 CET"
    finally:
        if old is None:
            del os.environ["TZ"]
        else:
            os.environ["TZ"] = old
        _time.tzset()
    lines = [EventLine(f"t{i}", "led_request_failed", "robot r1: radio link down")
             for i in range(5)]  # fmt: skip
    lines.append(EventLine("t9", "robot_lost", "robot r2 is lost"))
    text = events_text(lines).splitlines()
    assert text == [
        "- `t0` **led request failed** robot r1: radio link down (x5)",
        "- `t9` robot r2 is lost",  # the message says it: no "robot lost" before it
    ]


def test_coverage_uses_the_chosen_robot_and_follows_map_changes() -> None:
    from web.panels.coverage import CoveragePanel

    site = grid_site()
    server = viser.ViserServer("127.0.0.1", 0, verbose=False)
    try:
        panel = CoveragePanel(server, site, lambda t, b: None)
        panel.gui_by.value = "landmarks in view"  # type: ignore[misc]
        panel.gui_robot.value = "r2"  # type: ignore[misc]
        text = panel.show()
        assert "camera of **r2**" in text and "map of 12 landmarks" in text
        assert not panel.refresh(site.landmarks())  # the first look: nothing changed yet
        assert not panel.refresh(site.landmarks())
        site.delete_landmark(10, actor="t")
        assert panel.refresh(site.landmarks())
        assert "map of 11 landmarks" in panel.gui_text.content
    finally:
        server.stop()


def test_battery_html_keeps_its_columns_and_its_length() -> None:
    from web.battery_table import COLUMN_WIDTHS, battery_html

    lms = [LandmarkState(i, 0, 0, 2.5, supply_mv=3000 - i, model_days=100.0 + i) for i in range(39)]
    html = battery_html(lms, "id", max_rows=10)
    assert "table-layout:fixed" in html and html.count("<col ") == len(COLUMN_WIDTHS)
    assert html.count("<tr>") == 11 and "and 29 more" in html  # header + 10 rows
    assert "settle within the first hour" in html  # what "days" means, on the panel


def test_window_classes() -> None:
    from web.layout import window_class

    assert window_class(390) == "phone"
    assert window_class(1280) == "desktop"
    assert window_class(1920) == "wide"
