"""The live survey's API without a drive: accepting landmark by landmark, what is refused
(a 4xx naming it, nothing written), cancel; and the blink choice and the in-memory drive."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from live.survey.blinks import blink_choice, needed_by_others
from live.survey.live import LiveDrive
from localizer.events import FrameObserved, LedsChanged, OdometryMeasured, SpotsObserved
from localizer.robot import RobotGeometry
from sim.cameras import wide_angle_camera
from survey.result import LandmarkEstimate, SurveyResult
from tests.server.conftest import Api

S = "/api/v1/commissioning/survey"


def estimate(
    lid: int, xyz: tuple[float, float, float], sigma: float, **kw: object
) -> LandmarkEstimate:
    cov = np.diag([sigma**2, (sigma / 2) ** 2, (sigma / 3) ** 2])
    return LandmarkEstimate(lid, np.array(xyz), cov, observations=20, views=6, rms_px=0.4,
                            max_px=1.0, given=np.array([xyz[0] - 0.1, xyz[1], xyz[2]]),
                            **kw)  # type: ignore[arg-type]  # fmt: skip


def solved(api: Api) -> None:
    """Landmarks 1 (locked: the anchor), 2, 3 (flagged) and 4 in the map, and a survey
    result for 1-3 as the solver leaves it (the drive itself is the live tests')."""
    h = api.h("admin")
    for lid in (1, 2, 3, 4):
        body = {"id": lid, "x": float(lid), "y": 0.0, "z": 2.5, "locked": lid == 1}
        assert api.client.post("/api/v1/landmarks", json=body, headers=h).status_code == 201
    result = SurveyResult(
        {1: estimate(1, (1.0, 0.0, 2.5), 0.0, anchor=True),
         2: estimate(2, (2.05, 0.01, 2.51), 0.004, anchor=False),
         3: estimate(3, (3.9, 0.0, 2.5), 0.02, anchor=False, flags=("moved, or radios swapped?",))},
        (4,), np.zeros(2, dtype=np.int64), np.zeros((2, 3)), (1.0, 1.0, 1.0), (0.0,) * 6, 0.4,
        1.0, 5, True,
    )  # fmt: skip
    svc = api.services.survey
    with svc._lock:  # a finished survey's state, as `_solve` leaves it
        svc._state, svc._robot, svc._result = "done", "r1", result


def xyz(api: Api, lid: int) -> tuple[float, float, float]:
    lm = api.services.map.get(lid)
    return (lm.x, lm.y, lm.z)


def test_accept_landmark_by_landmark_and_every_refusal_writes_nothing(api: Api) -> None:
    solved(api)
    c, h = api.client, api.h("admin")
    st = c.get(S, headers=api.h("viewer")).json()
    props = {p["landmark_id"]: p for p in st["proposals"]}
    assert {i: p["state"] for i, p in props.items()} == {1: "anchor", 2: "converged", 3: "flagged"}
    assert props[2]["ellipse_major_m"] == pytest.approx(0.004)
    assert props[2]["ellipse_minor_m"] == pytest.approx(0.002)
    assert props[2]["moved_m"] == pytest.approx(0.1)  # from the map's given position
    assert st["unseen"] == [4] and st["converged_sigma_m"] == pytest.approx(0.005)
    before = {i: xyz(api, i) for i in (1, 2, 3, 4)}
    n_audit = len(api.services.map.audit(limit=100))
    for body, words in (
        ({"landmarks": [2, 2]}, "2 given more than once"),
        ({"landmarks": [2, 4]}, "4 not surveyed"),
        ({"landmarks": [1]}, "1 not surveyed (or anchors)"),
        ({"landmarks": [2, 3]}, "flagged by the survey (3: moved, or radios swapped?)"),
    ):
        r = c.post(S + "/accept", json=body, headers=h)
        assert r.status_code == 422 and words in r.json()["detail"], (body, r.text)
    for body in ({"landmarks": "2"}, {"landmarks": [-1]}, {"landmark": [2]}):
        r = c.post(S + "/accept", json=body, headers=h)
        assert r.status_code == 422 and "landmark" in r.json()["detail"], (body, r.text)
    assert (
        c.post(S + "/accept", json={"landmarks": [2]}, headers=api.h("operator")).status_code == 403
    )
    assert {i: xyz(api, i) for i in (1, 2, 3, 4)} == before  # nothing written
    assert len(api.services.map.audit(limit=100)) == n_audit
    # one landmark: written through the data layer, audited as the survey's, undoable
    r = c.post(S + "/accept", json={"landmarks": [2]}, headers=h)
    assert r.status_code == 200 and r.json()["accepted"] == [2], r.text
    assert xyz(api, 2) == pytest.approx((2.05, 0.01, 2.51))
    assert xyz(api, 3) == before[3]
    audit = api.services.map.audit(limit=1)[0]
    assert audit.landmark_id == 2 and audit.actor.endswith("(survey)")
    # a flagged one only when asked; then every unflagged one ("as a whole") is 2 alone
    r = c.post(S + "/accept", json={"landmarks": [3], "include_flagged": True}, headers=h)
    assert r.status_code == 200 and r.json()["accepted"] == [2, 3], r.text
    assert xyz(api, 3) == pytest.approx((3.9, 0.0, 2.5))
    assert c.post(S + "/accept", json={}, headers=h).json()["accepted"] == [2, 3]
    # a landmark locked since (an anchor now) is not overwritten
    assert c.patch("/api/v1/landmarks/2", json={"locked": True}, headers=h).status_code == 200
    r = c.post(S + "/accept", json={"landmarks": [2]}, headers=h)
    assert r.status_code == 422 and "2 are locked in the map" in r.json()["detail"]
    r = c.post(S + "/cancel", headers=h)
    assert r.status_code == 200 and r.json()["state"] == "idle" and r.json()["proposals"] == []
    r = c.post(S + "/accept", json={"landmarks": [2]}, headers=h)
    assert r.status_code == 409 and "no survey estimate" in r.json()["detail"]


def test_blink_choice_needs_in_view_and_untracked() -> None:
    blinked = {1: 3, 2: 1, 3: 1, 4: 0}
    # 4 is blinked least but out of view; 2 and 3 tie: the lower ID
    assert blink_choice([1, 2, 3, 4], [1, 2, 3], set(), blinked) == 2
    assert blink_choice([1, 2, 3, 4], [1, 2, 3], {2}, blinked) == 3  # r2 tracks 2
    assert blink_choice([1, 4], [2, 3], set(), blinked) is None  # nothing needed in view
    assert blink_choice([1, 4], None, set(), blinked) == 4  # no pose: any candidate
    assert blink_choice([1], [1], {1}, blinked) is None
    # an anchor not identified yet goes first, however often it was blinked
    assert blink_choice([1, 2, 3, 4], [1, 2, 3], set(), blinked, first={1}) == 1
    # but one the robot's fix used goes before one merely expected (at the image's edge,
    # too faint to see: a wasted blink), anchor or not
    assert blink_choice([1, 2, 3, 4], [1, 2, 3], set(), blinked, first={1}, seen=(3,)) == 3
    assert blink_choice([1, 2, 3], [1, 2, 3], set(), blinked, first={1}, seen=(1, 3)) == 1


def test_other_robots_keep_three_landmarks_through_a_dark_window() -> None:
    # r2 fixes from 1-5: any one may go dark; r3 from 6, 7, 8: none of them may
    assert needed_by_others([(1, 2, 3, 4, 5), (6, 7, 8)], keep=3) == {6, 7, 8}
    assert needed_by_others([(1, 2, 3, 4)], keep=3) == set()
    assert needed_by_others([(1, 2)], keep=2) == {1, 2}
    assert needed_by_others([()], keep=3) == set()  # lost or dead reckoning: nothing used
    # an anchor under a robot that sees plenty is blinked (it used to be spared for ever)
    spared = needed_by_others([(1, 2, 3, 4, 5)], keep=3)
    assert blink_choice([1, 9], [1, 9], spared, {1: 0, 9: 0}, first={1}) == 1


def test_live_drive_keeps_spots_wheels_and_led_states_in_time_order() -> None:
    cam = wide_angle_camera("pinhole")
    drive = LiveDrive([], cam, RobotGeometry(wheel_base=0.4), queue_frames=4)
    try:
        img = np.zeros((cam.height, cam.width), np.uint8)
        img[100:104, 200:204] = 250
        drive.add(FrameObserved(10, img))
        drive.add(OdometryMeasured(11, 0.1, 0.2))
        drive.add(OdometryMeasured(11, 0.1, 0.2))  # a repeat is dropped
        drive.add(LedsChanged(12, frozenset({1}), changing=frozenset({2})))
        drive.add(FrameObserved(20, np.zeros_like(img)))
        for _ in range(500):
            if drive.frames == 2:
                break
            threading.Event().wait(0.01)
        snap = drive.snapshot()
        assert snap.frame_t_ns.tolist() == [10, 20]
        np.testing.assert_allclose(snap.frame_spots[0], [[201.5, 101.5]], atol=0.05)
        assert snap.frame_spots[1].shape == (0, 2)
        assert snap.odom_t_ns.tolist() == [11] and snap.odom_v.tolist() == [[0.1, 0.2]]
        # as a recording keeps it: 2, its command in flight, may be lit already: written lit
        assert snap.leds == [LedsChanged(12, frozenset({1, 2}))]
    finally:
        drive.close()
    spots = LiveDrive([], cam, RobotGeometry(wheel_base=0.4))  # a robot sending spots
    try:  # a blink's frames: counted from the confirmed switch on, not from the request
        spots.add(LedsChanged(100, frozenset({1, 2})))
        spots.add(LedsChanged(200, frozenset({1, 2}), changing=frozenset({2})))  # darkening
        frame = [np.array([[5.0, 6.0]]), np.ones(1), np.ones(1)]
        spots.add(SpotsObserved(210, *frame))  # type: ignore[arg-type]
        assert spots.frames_since_switch(2, lit=False) == 0
        assert spots.frames_since_switch(2, lit=True) == 0  # in flight: neither for sure
        spots.add(LedsChanged(250, frozenset({1})))  # confirmed dark at 250
        assert spots.frames_since_switch(2, lit=False) == 0  # 210 was before
        spots.add(LedsChanged(260, frozenset({1}), changing=frozenset({3})))  # another LED
        for t in (270, 300, 330):
            spots.add(SpotsObserved(t, *frame))  # type: ignore[arg-type]
        assert spots.frames_since_switch(2, lit=False) == 3  # still dark since 250
        assert spots.frames_since_switch(2, lit=True) == 0
        assert spots.frames_since_switch(1, lit=True) == 4  # lit all along since 100
    finally:
        spots.close()
    spots = LiveDrive([], cam, RobotGeometry(wheel_base=0.4))
    try:
        spots.add(SpotsObserved(5, np.array([[5.0, 6.0]]), np.ones(1), np.ones(1)))
        spots.add(SpotsObserved(4, np.array([[1.0, 1.0]]), np.ones(1), np.ones(1)))  # late
        assert spots.snapshot().frame_t_ns.tolist() == [5]
    finally:
        spots.close()


def test_a_restart_keeps_the_running_estimate_to_accept_or_go_on_from(api: Api) -> None:
    """The running estimate is in the data directory after each update; a server started
    on it shows it (interrupted), accepts from it, and cancel drops it with its file."""
    from live.survey.estimator import STATE_FILE
    from live.survey.service import LiveSurvey
    from survey.incremental import IncrementalSurvey
    from survey.incremental_file import save

    solved(api)
    svc = api.services.survey
    path = api.services.settings.data_dir / STATE_FILE
    assert svc._result is not None
    save(IncrementalSurvey(result=svc._result, updates=7), path, {"robot": "r1"})
    s = api.services
    again = LiveSurvey(s.map, s.robots, s.leds, s.recordings, data_dir=path.parent)
    st = again.status()
    assert st.state == "interrupted" and st.robot == "r1" and st.estimates == 7
    assert "restarted" in st.message and "start again" in st.message
    assert {p.landmark_id: p.state for p in st.proposals} == {
        1: "anchor",
        2: "converged",
        3: "flagged",
    }
    again.accept([2], actor="admin")
    assert xyz(api, 2) == pytest.approx((2.05, 0.01, 2.51))
    assert api.services.map.get(2).sigma_m == pytest.approx(0.004)
    again.cancel(actor="admin")
    assert again.status().state == "idle" and not path.exists()
    path.write_bytes(b"garbage")  # a file that is no state: logged, the survey starts idle
    assert (
        LiveSurvey(s.map, s.robots, s.leds, s.recordings, data_dir=path.parent).status().state
        == "idle"
    )
