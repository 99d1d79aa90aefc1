from __future__ import annotations

import numpy as np
import pytest

from tests.web.memsite import grid_site
from web.wizard import IdentificationWizard, WizardConfig

FAST = WizardConfig(
    frame_timeout_s=0.5, settle_s=0.0, poll_s=0.001, led_check_s=0.0, fix_settle_s=0.0
)


def test_wizard_lights_each_alone_saves_true_positions_and_restores_leds() -> None:
    site = grid_site(doubted={15: (0.3, -0.2), 16: (-0.25, 0.1)})
    before = site.lit()
    wiz = IdentificationWizard(site, FAST)
    assert [c.landmark_id for c in site.to_identify()] == [15, 16]
    m = wiz.start("r1", site.to_identify(), actor="alice")
    assert site.lit() == frozenset({15}) and site.held
    assert m.landmark_id == 15 and m.position is not None
    np.testing.assert_allclose(m.position, site.truth[15], atol=1e-6)
    assert wiz.state.progress == 0.0
    m2 = wiz.confirm(actor="alice")
    assert m2 is not None and m2.landmark_id == 16
    assert site.lit() == frozenset({16})
    assert wiz.state.progress == 50.0
    assert wiz.confirm(actor="alice") is None
    assert wiz.state.phase == "done" and wiz.state.saved == [15, 16]
    for lid in (15, 16):
        lm = site.map[lid]
        np.testing.assert_allclose([lm.x, lm.y, lm.z], site.truth[lid], atol=1e-6)
    assert site.lit() == before and not site.held
    assert [a[:3] for a in site.audit] == [("alice", "update", 15), ("alice", "update", 16)]


def test_cancel_restores_every_led_and_skip_saves_nothing() -> None:
    site = grid_site(doubted={11: (0.2, 0.0), 12: (0.2, 0.0)})
    site.set_leds(frozenset({10, 11, 13, 14, 15}), actor="t")
    before = site.lit()
    wiz = IdentificationWizard(site, FAST)
    wiz.start("r1", [11, 12], actor="bob")
    wiz.skip(actor="bob")
    assert site.lit() == frozenset({12})
    wiz.cancel(actor="bob")
    assert site.lit() == before
    assert wiz.state.phase == "cancelled" and wiz.state.skipped == [11]
    assert site.audit == []


def test_a_landmark_whose_radio_is_silent_neither_stalls_nor_fools_the_wizard() -> None:
    site = grid_site(doubted={15: (0.3, -0.2), 16: (-0.25, 0.1)})
    site.dead = frozenset({12, 16})  # flat batteries: 12 elsewhere, 16 to be identified
    wiz = IdentificationWizard(site, FAST)
    m = wiz.start("r1", [15, 16], actor="x")
    assert m.landmark_id == 15 and m.position is not None  # 12 silent: 15 still lit alone
    np.testing.assert_allclose(m.position, site.truth[15], atol=1e-6)
    m2 = wiz.confirm(actor="x")
    assert m2 is not None and m2.landmark_id == 16 and m2.position is None
    assert "16 does not answer its radio" in m2.message
    assert wiz.skip(actor="x") is None
    assert wiz.state.saved == [15] and wiz.state.skipped == [16] and not site.held


def test_manual_position_and_errors() -> None:
    site = grid_site(doubted={13: (0.2, 0.0)})
    wiz = IdentificationWizard(site, FAST)
    with pytest.raises(ValueError, match="not running"):
        wiz.confirm(actor="x")
    with pytest.raises(ValueError, match="unknown robot"):
        wiz.start("r9", [13], actor="x")
    wiz.start("r1", [13], actor="x")
    with pytest.raises(ValueError, match="already running"):
        wiz.start("r1", [13], actor="x")
    wiz.confirm(actor="x", position=(3.1, 0.05, 2.6))
    assert (site.map[13].x, site.map[13].y, site.map[13].z) == (3.1, 0.05, 2.6)


def test_out_of_view_landmark_gives_no_position_but_a_reason() -> None:
    site = grid_site()
    site.poses["r1"] = (-8.0, -8.0, 0.0)  # far away: nothing in view, no fix
    wiz = IdentificationWizard(site, FAST)
    m = wiz.start("r1", [10], actor="x")
    assert m.position is None and "no spot seen" in m.message
    with pytest.raises(ValueError, match="no measured position"):
        wiz.confirm(actor="x")


def test_abandon_releases_the_hold_without_touching_leds() -> None:
    site = grid_site()
    wiz = IdentificationWizard(site, FAST)
    wiz.start("r1", [12], actor="x")
    sent = len(site.led_log)
    wiz.abandon()
    assert wiz.state.phase == "cancelled" and not site.held
    assert len(site.led_log) == sent


def test_a_new_radio_from_discovery_is_lit_alone_and_becomes_a_landmark() -> None:
    site = grid_site(doubted={15: (0.3, -0.2)})
    site.radios["0013A20041000063"] = np.array([1.7, 1.4, 2.5])  # not in the map
    before = site.lit()
    found = site.to_identify(discover=True)
    assert [(c.landmark_id, c.radio) for c in found] == [(15, None), (63, "0013A20041000063")]
    wiz = IdentificationWizard(site, FAST)
    wiz.start("r1", found, actor="carol")
    assert site.lit() == frozenset({15}) and site.radio_lit == set()  # the radio darkened
    m2 = wiz.confirm(actor="carol")
    assert m2 is not None and m2.landmark_id == 63
    assert site.lit() == frozenset() and site.radio_lit == {"0013A20041000063"}  # alone
    assert m2.position is not None
    np.testing.assert_allclose(m2.position, [1.7, 1.4, 2.5], atol=1e-6)  # at the map's median
    assert "from the map" not in m2.message
    assert wiz.confirm(actor="carol") is None
    lm = site.map[63]
    assert lm.radio == "0013A20041000063"
    np.testing.assert_allclose([lm.x, lm.y, lm.z], [1.7, 1.4, 2.5], atol=1e-6)
    assert [a[:3] for a in site.audit] == [("carol", "update", 15), ("carol", "create", 63)]
    assert site.lit() == before | {63} and not site.held  # the new landmark lit like the rest


def test_skipped_and_cancelled_radios_are_left_lit() -> None:
    site = grid_site()
    site.radios["0013A20041000063"] = np.array([1.7, 1.4, 2.5])
    site.radio_lit.add("0013A20041000063")
    before = site.lit()
    wiz = IdentificationWizard(site, FAST)
    new = site.to_identify(discover=True)
    wiz.start("r1", [12, *new], actor="x")
    assert site.radio_lit == set()
    m = wiz.skip(actor="x")
    assert m is not None and site.radio_lit == {"0013A20041000063"}
    wiz.cancel(actor="x")
    assert site.lit() == before and site.radio_lit == {"0013A20041000063"}
    assert 63 not in site.map and site.audit == []
