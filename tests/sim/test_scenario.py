from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from sim.build import build_world, default_address, seed_generators
from sim.routes import Goto, TurnTo, Wait
from sim.scenario import SCENARIOS, load_scenario, scenario_from_dict

BASE: dict[str, Any] = {
    "name": "t",
    "landmarks": [{"id": 1, "x": 0, "y": 0}, {"id": 2, "x": 1.2, "y": 0, "z": 2.4}],
    "robots": [
        {"name": "a", "start": [0, 0, 90], "route": {"waypoints": [[1, 0], [1, 1]]}},
        {"name": "b", "start": [0, 0, 0], "route": {"waypoints": [[1, 0]], "dwell_s": 2}},
    ],
}


@pytest.mark.parametrize("name", SCENARIOS)
def test_builtin_scenarios_load(name: str) -> None:
    scenario = load_scenario(name)
    assert scenario.name == name
    assert scenario.robots and scenario.landmarks
    assert all(r.route.steps for r in scenario.robots)


def test_demo_has_three_robots_and_hostile_has_its_hazards() -> None:
    assert len(load_scenario("demo").robots) >= 3
    hostile = load_scenario("hostile")
    assert {e.kind for e in hostile.extended} == {"lamp", "sunlight"}
    assert hostile.glints and hostile.people and hostile.bumps
    assert any(lm.radio_dead for lm in hostile.landmarks)
    assert len({lm.z for lm in hostile.landmarks}) > 5
    cam = hostile.robots[0].camera
    assert cam.offset_xy_m != (0.0, 0.0) and cam.yaw_rad != 0.0


def test_paper_testbed_geometry() -> None:
    s = load_scenario("paper_testbed")
    p = np.array([[lm.x, lm.y, lm.z] for lm in s.landmarks])
    d = np.linalg.norm(p[:, None] - p[None], axis=2)[np.triu_indices(3, 1)]
    np.testing.assert_allclose(d, 1.2, atol=1e-3)
    np.testing.assert_allclose(p[:, 2], 2.5)
    turns = [st for st in s.robots[0].route.steps if isinstance(st, TurnTo)]
    assert len(turns) >= 36
    gotos = {(st.x, st.y) for st in s.robots[0].route.steps if isinstance(st, Goto)}
    assert len(gotos) == 20


def test_scenario_fields_and_defaults() -> None:
    s = scenario_from_dict(BASE, source="t.yaml")
    assert s.landmarks[0].z == 2.5 and s.landmarks[1].z == 2.4
    assert s.robots[0].start == (0.0, 0.0, pytest.approx(math.pi / 2))
    assert s.robots[0].camera.lens == "fisheye"
    steps = s.robots[1].route.steps
    assert isinstance(steps[0], Goto) and steps[1] == Wait(2.0)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["robots"][1]["route"]["waypoints"].append([1, "a"]),
         r"t\.yaml: robots\[1\]\.route\.waypoints\[1\]: expected \[x, y\]"),
        (lambda d: d["robots"][0].update(start=[0, 0]),
         r"t\.yaml: robots\[0\]\.start: expected \[x, y, theta_deg\]"),
        (lambda d: d["robots"][0].update(speed=3),
         r"t\.yaml: robots\[0\]: unknown field\(s\) \['speed'\]"),
        (lambda d: d["landmarks"][1].update(id=1), r"landmark id 1 appears twice"),
        (lambda d: d["landmarks"][0].update(x="near"), r"landmarks\[0\]\.x: expected a number"),
        (lambda d: d["robots"][0].update(camera={"lens": "zoom"}),
         r"robots\[0\]\.camera\.lens: expected one of \['pinhole', 'fisheye', 'wide_radtan'\]"),
        (lambda d: d["robots"][0].pop("route"), r"robots\[0\]: missing field 'route'"),
        (lambda d: d.update(render={"psf_sigma_px": -1}), r"render: RenderConfig: psf_sigma_px"),
        (lambda d: d["robots"][1].update(name="a"), r"robots: robot names must be unique"),
        (lambda d: d.update(radio={"latency_s": [0.2, 0.1]}), r"radio\.latency_s: expected 0 <="),
    ],
)  # fmt: skip
def test_bad_scenario_names_the_field(edit: Any, message: str) -> None:
    doc = copy.deepcopy(BASE)
    edit(doc)
    with pytest.raises(ValueError, match=message):
        scenario_from_dict(doc, source="t.yaml")


def test_load_scenario_from_file_and_errors(tmp_path: Path) -> None:
    path = tmp_path / "site.yaml"
    path.write_text(yaml.safe_dump(BASE))
    assert load_scenario(path).robots[1].name == "b"
    with pytest.raises(ValueError, match="no such scenario file"):
        load_scenario(tmp_path / "missing.yaml")
    path.write_text("robots: [\n")
    with pytest.raises(ValueError, match="invalid YAML"):
        load_scenario(path)


def test_world_is_seeded_and_survey_differs_from_truth() -> None:
    s = load_scenario("demo")
    a = build_world(s, seed_generators(s.seed, 1)[0])
    b = build_world(s, seed_generators(s.seed, 1)[0])
    ra, rb = a.landmark_records(), b.landmark_records()
    assert ra == rb
    lm = a.landmarks[100]
    err = np.linalg.norm(lm.p_true - lm.p_surveyed)
    assert 0 < err < 0.03
    assert ra[0]["radio"] == default_address(100) == "0013A20041000064"


def test_panels_make_every_landmark_a_passive_light_rendered_as_a_blob() -> None:
    from localizer.camera import T_body_camera_upward, predict_pixels
    from localizer.geometry import T_world_body_from_pose
    from localizer.landmark_map import LandmarkMap
    from localizer.spots import DetectionConfig, detect_spots
    from sim.render import render_frame
    from tests.localizer.cases import fisheye_camera

    doc = copy.deepcopy(BASE)
    doc["panels"] = {"width_m": 0.6, "length_m": 1.2, "angle_deg": 90, "map_sigma_m": 0.04}
    sc = scenario_from_dict(doc, source="t.yaml")
    assert sc.panels is not None and sc.panels.brightness == 300.0
    world = build_world(sc, np.random.default_rng(0))
    recs = world.landmark_records()
    assert all(r["passive"] and r["size_m"] == 1.2 and r["sigma_m"] == 0.04 for r in recs)
    lmap = LandmarkMap.from_records(recs)
    assert lmap.passive is not None and bool(np.all(lmap.passive))
    # no LED point source: the panels are extended sources, one per landmark
    assert len(world.point_sources(np.zeros(3))[0]) == 0 and len(world.extended) == 2
    cam = fisheye_camera(T_body_camera_upward(height=0.3))
    img = render_frame(cam, T_world_body_from_pose(0.6, 0.0, 0.0), [], [], rng=None,
                       extended=world.extended)  # fmt: skip
    spots = detect_spots(img, DetectionConfig(max_area_px=40_000, max_elongation=5))
    assert len(spots) == 2 and np.all(spots.areas > 1000)  # two panels, 0.6 m either side
    centres = np.array([lm.p_true for lm in world.landmarks.values()])
    px, _ = predict_pixels(cam, T_world_body_from_pose(0.6, 0.0, 0.0), centres)
    d = np.hypot(*(spots.pixels[:, None, :] - px[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    assert np.all(d < 5.0)  # where its centre projects, but for the perspective (3.5 px here)
    with pytest.raises(ValueError, match="panels"):
        scenario_from_dict({**doc, "panels": {"width_m": 0.0}}, source="t.yaml")
