"""The robustness matrix's scorer on one matrix scenario, where the answer is known: the true
poses score zero error, deliberately wrong landmark IDs and a wrong pose are counted, and a
recovery after a kidnap is timed. Plus the matrix files themselves load."""

from __future__ import annotations

import dataclasses
import io
import math
from pathlib import Path

import numpy as np
import pytest

from bench.robustness import MATRIX_FILES, _row, comparison, load_matrix, site_truth
from bench.robustness_score import FrameResult, SiteTruth, score, wrong_ids
from irloc.simulated_recording import simulate_recording
from localizer.camera import predict_pixels
from localizer.geometry import T_world_body_from_pose
from recording.reader import read_groundtruth
from recording.replay_cli import replay
from sim.cameras import CALIBRATION_LEVELS
from sim.offline import recording_site
from sim.scenario import load_scenario

MATRIX = Path(__file__).resolve().parents[2] / "bench" / "robustness"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object, object]:
    """grid40's fast turner, 3 s, realistic calibration error: recording, world, rig."""
    sc = load_scenario(MATRIX / "grid40.yaml").with_calibration(CALIBRATION_LEVELS["realistic"])
    rec = tmp_path_factory.mktemp("rb") / "grid40"
    simulate_recording(sc, rec, duration_s=3.0, robot="turner")
    _, world, rig, _ = recording_site(sc, robot="turner")
    return rec, world, rig


def _truth(rec: Path) -> tuple[list[int], dict[int, tuple[float, float, float]]]:
    t, gt = read_groundtruth(rec)
    return [int(x) for x in t], {
        int(x): (float(a), float(b), float(c)) for x, (a, b, c) in zip(t, gt, strict=True)
    }


def _visible_ids(site: object, pose: tuple[float, float, float]) -> tuple[int, ...]:
    _, ok = predict_pixels(site.camera_true, site.T_world_body(*pose), site.sources)  # type: ignore[attr-defined]
    return tuple(int(i) for i, v in zip(site.source_ids, ok, strict=True) if v and i >= 0)  # type: ignore[attr-defined]


def test_true_poses_with_the_true_ids_score_zero(recorded: tuple[Path, object, object]) -> None:
    rec, world, rig = recorded
    site = site_truth(world, rig)  # type: ignore[arg-type]
    times, truth = _truth(rec)
    results = [FrameResult(t, truth[t], "landmark", _visible_ids(site, truth[t])) for t in times]
    assert min(len(r.landmark_ids) for r in results) > 40  # a dense grid in view
    s = score(results, truth.__getitem__, site, t_start_ns=times[0])
    assert (s.p95_m, s.max_m, s.heading_max_rad) == (0.0, 0.0, 0.0)
    assert (s.wrong_id, s.gross, s.misidentified, s.dr_off) == (0, 0, 0, 0)
    assert s.modes == {"landmark": len(times)} and s.share("landmark") == 1.0


def test_wrong_ids_and_wrong_poses_are_counted(recorded: tuple[Path, object, object]) -> None:
    rec, world, rig = recorded
    site = site_truth(world, rig)  # type: ignore[arg-type]
    times, truth = _truth(rec)
    results = []
    for k, t in enumerate(times):
        x, y, th = truth[t]
        ids = _visible_ids(site, truth[t])
        if k % 10 == 0:  # the classic grid ambiguity: every spot given the ID one column
            # over (+40 cm in x), and the pose that fits them (40 cm off)
            ids = tuple(i + 1 for i in ids if (i - 100) % 12 < 11)
            x += 0.4
        results.append(FrameResult(t, (x, y, th), "landmark", ids))
    n10 = len(range(0, len(times), 10))
    # one frame with the right pose names a landmark it cannot see (not gross)
    t5 = times[5]
    lms = world.landmarks  # type: ignore[attr-defined]
    unseen = max(lms, key=lambda i: float(np.hypot(*(lms[i].p_true[:2] - truth[t5][:2]))))
    results[5] = FrameResult(t5, truth[t5], "landmark", (*results[5].landmark_ids, unseen))
    # a dead-reckoning pose 30 cm off: counted on its own, not as misidentified
    x6, y6, th6 = truth[times[6]]
    results[6] = FrameResult(times[6], (x6 + 0.3, y6, th6), "dead_reckoning")
    s = score(results, truth.__getitem__, site)
    assert (s.wrong_id, s.gross, s.misidentified, s.dr_off) == (n10 + 1, n10, n10 + 1, 1)
    assert s.max_m == pytest.approx(0.4)
    assert s.notes[0].startswith("t=0.00 s: ") and "is landmark" in s.notes[0]


def test_a_body_tilted_by_a_bump_is_not_a_wrong_id(recorded: tuple[Path, object, object]) -> None:
    # A landmark and a glint beside it; the body pitched 5 deg by a floor bump. The right
    # planar pose naming the landmark is right; the same pose naming it next to the glint's
    # image is not (the glint sits where a level body would see the landmark).
    _, _, rig = recorded
    c, s = math.cos(math.radians(5.0)), math.sin(math.radians(5.0))
    pitch = np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]], dtype=float)

    def tilted(x: float, y: float, th: float) -> np.ndarray:
        return T_world_body_from_pose(x, y, th) @ pitch

    landmark = np.array([0.3, 0.1, 2.5])
    # the glint: where the pitched camera sees what a level one sees at the landmark
    glint = (tilted(0, 0, 0) @ np.append(landmark, 1.0))[:3]
    assert 0.1 < float(np.hypot(*(glint - landmark)[:2])) < 0.4
    site = SiteTruth(
        sources=np.array([landmark, glint]), source_ids=np.array([1, -1]),
        camera_true=rig.camera_true, camera_nominal=rig.camera_true,  # type: ignore[attr-defined]
        surveyed={1: landmark}, T_world_body=tilted,
    )  # fmt: skip
    assert wrong_ids(site, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), [1]) == []
    # an estimate that puts the landmark onto the glint (the body's own tilt taken away)
    dx = float(landmark[0] - glint[0])
    bad = wrong_ids(site, (dx, 0.0, 0.0), (0.0, 0.0, 0.0), [1])
    assert len(bad) == 1 and "is a glint" in bad[0]


def test_recovery_after_a_kidnap_is_timed(recorded: tuple[Path, object, object]) -> None:
    rec, _, _ = recorded
    times, truth = _truth(rec)
    pick, drop, back = times[10], times[20], times[50]  # back 1 s after the drop (30 Hz)
    results = []
    for t in times:
        x, y, th = truth[t]
        if pick < t < back:
            results.append(
                FrameResult(t, (x + 2.0, y, th), "dead_reckoning" if t < drop else "lost")
            )
        else:
            results.append(FrameResult(t, (x, y, th), "landmark"))
    s = score(results, truth.__getitem__, None, kidnaps=[(pick, drop)])
    assert s.recover_s == [pytest.approx((back - drop) * 1e-9)]
    assert s.dr_off == 0  # in the air or lost: not scored
    never = [dataclasses.replace(r, mode="lost") if r.t_ns > drop else r for r in results]
    assert score(never, truth.__getitem__, None, kidnaps=[(pick, drop)]).recover_s == [None]


def test_a_replay_of_the_recording_is_scored(recorded: tuple[Path, object, object]) -> None:
    rec, world, rig = recorded
    out = io.StringIO()
    replay(rec, out, threads=1)
    results = [_row(line) for line in out.getvalue().splitlines()[1:]]
    times, truth = _truth(rec)
    assert [r.t_ns for r in results] == times
    s = score(results, truth.__getitem__, site_truth(world, rig), t_start_ns=times[0])  # type: ignore[arg-type]
    assert sum(s.modes.values()) == len(times)
    assert s.modes.get("landmark", 0) > 0 and math.isfinite(s.p95_m)
    assert max(s.wrong_id, s.gross) <= s.misidentified <= s.wrong_id + s.gross


def test_every_matrix_run_loads_and_covers_each_level() -> None:
    runs = load_matrix(MATRIX_FILES[0], held_out=False)
    held = load_matrix(MATRIX_FILES[1], held_out=True)
    assert len({r.name for r in runs + held}) == len(runs + held)
    covers = " ".join(r.covers for r in runs)
    for level in ("fisheye", "wide radtan", "pinhole", "calib none", "calib realistic",
                  "calib poor", "axle", "yawed 90", "tilted", "grid 40 cm", "irregular",
                  "pairs with gaps", "ceiling +-12 cm", "turn 3 rad/s", "stop-and-go",
                  "wheel slip", "kidnap, no LED control", "kidnap, LED control", "glints",
                  "lamp", "sun", "dead LED", "people", "dropped", "floor tilt"):  # fmt: skip
        assert level in covers, level
    assert all(r.held_out for r in held) and all(20 <= r.duration_s <= 70 for r in runs + held)
    for r in runs + held:
        sc = r.build()
        assert sc.survey_sigma_m > 0 or "exact map" in r.covers
        robot = next(x for x in sc.robots if x.name == (r.robot or sc.robots[0].name))
        assert robot.wheel_radius_error != (0.0, 0.0)  # odometry bias everywhere
    assert np.isfinite([r.duration_s for r in runs]).all()


def test_the_comparison_shows_now_and_before() -> None:
    row = {"name": "a", "p95_m": 0.012, "heading_mean_rad": math.radians(0.04), "frames": 10,
           "modes": {"landmark": 9, "lost": 1}, "misidentified": 0, "recover_s": [2.5]}  # fmt: skip
    was = dict(row, p95_m=0.5, modes={"lost": 10}, misidentified=3, recover_s=[None])
    table = comparison([row, dict(row, name="new")], [was])
    assert "| a | 1.2 (50.0) | 0.040 (0.040) | 90 (0) | 10 (100) | 0 (3) | 2.5 (never) |" in table
    assert "| new | 1.2 | 0.040 | 90 | 10 | 0 | 2.5 |" in table
