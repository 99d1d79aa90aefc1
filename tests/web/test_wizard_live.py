"""The identification wizard on the running virtual site (no browser): LEDs switched through
the real gateway and simulated radio, frames rendered by the simulator, spots found by the
real detector, the position computed from the robot's own localized pose, saved through the
real data layer. The simulator's truth only checks the result."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from server.models import LandmarkUpdate
from tests.web.conftest import (
    LiveSite,
    landmark_always_in_view,
    nearest_landmarks,
    wait_localized,
)
from web.adapter import SiteAdapter
from web.measure import Measurement
from web.wizard import IdentificationWizard

pytestmark = pytest.mark.slow


class LoggingAdapter(SiteAdapter):
    """The real adapter, recording the LED states it asked for and saw."""

    def __init__(self, services: Any) -> None:
        super().__init__(services)
        self.led_log: list[frozenset[int]] = []
        self.lit_log: list[frozenset[int]] = []

    def lit(self) -> frozenset[int]:
        lit = super().lit()
        self.lit_log.append(lit)
        return lit

    def set_leds(self, lit: frozenset[int], *, actor: str) -> frozenset[int]:
        self.led_log.append(frozenset(lit))
        return super().set_leds(lit, actor=actor)


def measured_on_a_good_pose(
    wiz: IdentificationWizard, site: Any, services: Any, robot: str, m: Measurement | None
) -> Measurement:
    """The wizard's measurement, retried (as staff would press Retry) while the robot's own
    estimate for the frame was more than 1.5 cm off the truth: that is the localizer's error
    (checked with the truth; the wizard never sees it), not the viewer's."""
    for _ in range(3):
        assert m is not None
        if m.position is not None and m.view is not None and m.robot_pose is not None:
            truth = services.sim.true_pose_at(robot, m.view.t_ns)
            off = 0.0 if truth is None else np.hypot(*np.subtract(m.robot_pose[:2], truth[:2]))
            if off <= 0.015:
                return m
        wait_localized(site, robot, services)
        m = wiz.retry(actor="viewer:test")
    assert m is not None
    return m


def saved_error_m(services: Any, lid: int) -> float:
    saved, truth = services.map.get(lid), services.sim.world.landmarks[lid].p_true
    return float(np.hypot(saved.x - truth[0], saved.y - truth[1]))


def test_wizard_lights_each_alone_in_the_virtual_site_and_saves_true_positions(
    live_site: LiveSite,
) -> None:
    services = live_site.services
    world = services.sim.world
    site = LoggingAdapter(services)
    try:
        robot = "r2"
        wait_localized(site, robot, services)
        ids = nearest_landmarks(services, robot, 2)
        for lid in ids:  # doubted: 25 cm off in the map
            lm = services.map.get(lid)
            services.map.update(lid, LandmarkUpdate(x=lm.x + 0.25), actor="test")
        wait_localized(site, robot, services)  # still right with the others
        wiz = IdentificationWizard(site)
        m = wiz.start(robot, ids, actor="viewer:test")
        assert world.lit_ids() == {ids[0]}
        m = measured_on_a_good_pose(wiz, site, services, robot, m)
        assert m.position is not None, m.message
        m2 = wiz.confirm(actor="viewer:test")
        assert m2 is not None and world.lit_ids() == {ids[1]}
        m2 = measured_on_a_good_pose(wiz, site, services, robot, m2)
        assert m2.position is not None, m2.message
        assert wiz.confirm(actor="viewer:test") is None
        # restored to the state at the start (robots' own sweeps resume afterwards)
        assert site.led_log[-1] == site.lit_log[0]
        for lid in ids:
            assert saved_error_m(services, lid) < 0.02, services.map.get(lid)
        actions = [r.actor for r in services.map.audit(2)]
        assert actions == ["viewer:test", "viewer:test"]
    finally:
        site.close()


def test_a_radio_missing_from_the_map_is_found_by_discovery_and_placed(
    live_site: LiveSite,
) -> None:
    services = live_site.services
    site = SiteAdapter(services)
    try:
        robot = "r2"
        wait_localized(site, robot, services)
        lid = landmark_always_in_view(services, robot)
        address = services.map.get(lid).radio
        services.map.delete(lid, actor="test")  # its radio still answers
        found = site.to_identify(discover=True)
        new = [c for c in found if c.radio is not None]
        assert [(c.landmark_id, c.radio) for c in new] == [(lid, address)]  # "LM<id>"
        wiz = IdentificationWizard(site)
        wait_localized(site, robot, services)
        m = wiz.start(robot, new, actor="viewer:test")
        assert services.sim.world.lit_ids() == {lid}  # the radio's LED, alone
        m = measured_on_a_good_pose(wiz, site, services, robot, m)
        assert m.position is not None, m.message
        assert wiz.confirm(actor="viewer:test") is None
        lm = services.map.get(lid)
        assert lm.radio == address
        assert saved_error_m(services, lid) < 0.02, lm
        assert services.map.audit(1)[0].actor == "viewer:test"
        assert lid in site.lit()  # a landmark like the others now
    finally:
        site.close()


def test_a_landmark_moved_in_the_map_becomes_doubted_and_is_offered(live_site: LiveSite) -> None:
    services = live_site.services
    site = SiteAdapter(services)
    try:
        robot = "r2"
        wait_localized(site, robot, services)
        lid = landmark_always_in_view(services, robot)  # many chances to use it
        before = services.map.get(lid)
        services.map.update(lid, LandmarkUpdate(y=before.y + 0.5), actor="test")
        deadline = time.monotonic() + 60.0
        doubted: list[int] = []
        while time.monotonic() < deadline and lid not in doubted:
            time.sleep(0.5)
            doubted = [lm.id for lm in site.landmarks() if lm.doubted]
        assert lid in doubted, f"landmark {lid} not doubted; doubted: {doubted}"
        offered = {c.landmark_id: c for c in site.to_identify()}
        assert lid in offered and offered[lid].reason.startswith("doubted: expected in view")
        services.map.update(lid, LandmarkUpdate(y=before.y), actor="test")  # back: forgotten
        assert lid not in [lm.id for lm in site.landmarks() if lm.doubted]
    finally:
        site.close()
