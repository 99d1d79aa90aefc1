"""The schedule in a running site: the coordinator's normal state is the schedule, probes
darken one landmark of it, and robots identify and track under it (live/leds/)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest

from bench.virtual_site import parked, robot_stats, run_site, run_virtual
from live.leds.coordinator import LedCoordinator
from live.leds.wiring import localizer_config, schedule_config
from live.settings import Settings
from localizer.events import LedRequest
from sim.scenario import load_scenario
from sim.world import World
from tests.live.leds.test_coordinator import ALL, Inbox, settle
from tests.live.leds.test_coordinator import run_site as run_leds


def test_probes_darken_one_landmark_of_the_schedule_and_a_new_schedule_keeps_the_probe() -> None:
    normal = {1, 2, 4}

    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.normal = lambda: normal
        coord.renormal()
        await settle(coord)
        assert world.lit_ids() == {1, 2, 4}
        coord.request("r1", LedRequest(all_lit=True, dark=frozenset({2})))
        await settle(coord)
        assert world.lit_ids() == {1, 4}
        normal.clear()
        normal.update({2, 3})  # the schedule moves on while the probe is in force
        coord.renormal()
        await settle(coord)
        assert world.lit_ids() == {3}
        coord.request("r1", LedRequest(all_lit=True))  # identified: "all" = the schedule
        await settle(coord)
        assert world.lit_ids() == {2, 3}
        assert inbox.states()[-1] == {2, 3}

    run_leds(body, dwell_s=0.01)


def test_without_a_schedule_all_lit_means_every_landmark() -> None:
    async def body(coord: LedCoordinator, world: World, inbox: Inbox) -> None:
        coord.request("r1", LedRequest(all_lit=True, dark=frozenset({3})))
        await settle(coord)
        coord.renormal()
        await settle(coord)
        assert world.lit_ids() == ALL - {3}

    run_leds(body, dwell_s=0.01)


def _settings(sleep: float | None = None) -> Settings:
    return Settings(
        data_dir=Path(tempfile.mkdtemp()), led_policy="scheduled", radio_sleep_period_s=sleep
    )


@pytest.mark.slow
def test_robots_identify_and_track_under_the_schedule_and_most_landmarks_go_dark() -> None:
    """The demo site on virtual time with the scheduled policy: every robot gets its first
    fix (identification by darkening one landmark among the lit ones) and then tracks
    within a centimetre or two while well under half of the landmarks are lit."""
    run = run_virtual(run_site("demo", _settings(), 18.0, measure_from_s=12.0))
    for name in run.poses:
        s = robot_stats(run, name, settle_s=3.0)
        assert s["first_fix_s"] < 10.0, (name, s)
        assert s["p95_cm"] < 3.0, (name, s)
    assert sum(run.lit_samples) / len(run.lit_samples) / len(run.landmark_ids) < 0.5


@pytest.mark.slow
def test_an_idle_site_goes_dark_and_the_parked_robots_keep_their_pose() -> None:
    sc = parked(load_scenario("demo"), 60.0)
    run = run_virtual(run_site(sc, _settings(), 30.0, measure_from_s=28.0))
    assert max(run.lit_samples) <= 1  # the store-room landmark may be dead, or lit by none
    for name in run.poses:
        s = robot_stats(run, name, settle_s=3.0)
        assert s["p95_cm"] < 3.0, (name, s)


def test_sleeping_radios_stretch_the_identification_timeouts_and_the_lead_time() -> None:
    awake, asleep = _settings(), _settings(1.0)
    ident_awake = localizer_config(awake).identification
    ident_asleep = localizer_config(asleep).identification
    assert ident_asleep.led_timeout_s >= ident_awake.led_timeout_s + 1.0
    assert schedule_config(asleep, 0.25).latency_s >= 1.25
    assert schedule_config(asleep, 0.25).max_switches < schedule_config(awake, 0.25).max_switches
