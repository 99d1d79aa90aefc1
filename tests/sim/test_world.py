from __future__ import annotations

import numpy as np
import pytest

from lighting.battery import Battery
from sim.world import Glint, Person, SimLandmark, World


def _world(**kw: object) -> World:
    lms = {
        1: SimLandmark(1, np.array([0.0, 0.0, 2.5]), np.zeros(3), "0013A20041000001", Battery()),
        2: SimLandmark(2, np.array([2.0, 0.0, 2.5]), np.zeros(3), "0013A20041000002",
                       Battery(charge=0.1)),
    }  # fmt: skip
    return World(lms, **kw)  # type: ignore[arg-type]


def test_person_walks_back_and_forth_and_blocks_rays_below_head_height() -> None:
    person = Person(((0.0, -2.0), (0.0, 2.0)), speed_mps=1.0, radius_m=0.25, height_m=1.8)
    np.testing.assert_allclose(person.position(1.0), [0.0, -1.0])
    np.testing.assert_allclose(person.position(5.0), [0.0, 1.0])  # turned back at 4 s
    camera = np.array([0.0, -1.0, 0.3])
    # Camera right beside the person: the ray straight up passes through; at 1.0 m away the
    # ray to an LED above the person's far side passes below head height through them.
    blocked = person.blocks(
        1.0, camera + np.array([0.3, 0, 0]), np.array([[0.3, -1.0, 2.5], [-1.0, -1.0, 2.5]])
    )
    assert blocked.tolist() == [False, True]


def test_point_sources_follow_leds_batteries_glints_and_people() -> None:
    glint = Glint((0.2, 0.0, 2.5), 0.3, blink_period_s=2.0)
    person = Person(((2.0, 0.0), (2.0, 0.0001)), speed_mps=0.0)
    world = _world(glints=[glint], people=[person])
    # The camera 0.5 m from the person: the ray to landmark 2 passes through them below
    # head height; the one to landmark 1 leads away.
    p, i = world.point_sources(np.array([1.5, 0.0, 0.3]))
    assert p.shape == (3, 3)
    assert i[0] == pytest.approx(1.0, abs=0.02)
    assert i[1] == 0.0  # the person stands under landmark 2, between it and the camera
    assert i[2] == 0.3
    world.advance(1_500_000_000)  # glint is off in the second half of its period
    world.set_lit({2})
    p, i = world.point_sources(np.array([2.0, -1.5, 0.3]))
    assert len(p) == 1 and 0 < i[0] < 0.7  # landmark 2 alone, dim: its cells are low


def test_batteries_drain_with_time_only_when_advanced() -> None:
    world = _world()
    before = world.landmarks[1].battery.drawn_mah
    world.advance(3600 * 1_000_000_000)
    drawn = world.landmarks[1].battery.drawn_mah - before
    # ~54 mA LED + 17 mA for an XBee 3 receiving all the time (lighting.energy), for an hour
    assert drawn == pytest.approx(54.3 + 17.0, rel=0.02)
    assert world.landmark_records()[1]["radio"] == "0013A20041000002"


def test_frames_see_the_leds_as_they_were_at_their_own_time() -> None:
    clock = {"t": 1_000}
    world = _world(led_clock_ns=lambda: clock["t"])
    camera = np.array([1.0, 0.0, 0.3])
    clock["t"] = 5_000
    world.set_led(1, False)  # switched at t = 5000
    clock["t"] = 9_000
    world.set_led(2, False)  # switched at t = 9000
    assert len(world.point_sources(camera, t_ns=4_999)[0]) == 2  # both still lit then
    p, _ = world.point_sources(camera, t_ns=7_000)
    np.testing.assert_allclose(p, [[2.0, 0.0, 2.5]])  # landmark 1 off, 2 still lit
    assert len(world.point_sources(camera, t_ns=9_000)[0]) == 0
    assert len(world.point_sources(camera)[0]) == 0  # now
    world.set_led(2, False)  # no change: not logged
    world.advance(9_000 + 3_000_000_000)  # the log keeps the last `led_log_s` only
    assert len(world.point_sources(camera, t_ns=0)[0]) == 0


def test_fresh_cells_bring_a_flat_landmark_back() -> None:
    world = _world()
    world.landmarks[2].battery = Battery(charge=0.0)
    assert not world.landmarks[2].reachable
    world.replace_cells(2)
    assert world.landmarks[2].reachable and world.landmarks[2].battery.drawn_fraction == 0.0
    with pytest.raises(KeyError):
        world.replace_cells(99)
