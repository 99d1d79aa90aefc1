"""An agent's confident frames reach map upkeep: the spots sent with a pose are kept by its
runner (`AgentRunner.frame_at`) and counted by the upkeep service like a local robot's."""

from __future__ import annotations

import numpy as np

from fleet.payloads import AgentStatus, PoseMessage
from live.agent_runner import AgentRunner
from live.poses import PoseUpdate
from localizer.camera import sensor_from_camera
from localizer.events import PoseEstimate, SpotsObserved
from sim.cameras import wide_angle_camera


def _runner(published: list[PoseUpdate]) -> AgentRunner:
    cam = wide_angle_camera("fisheye")
    status = AgentStatus(
        source="sim-light", camera=sensor_from_camera(cam), wheel_base=0.36, max_speed=1.0,
        mode="landmark",
    )  # fmt: skip
    return AgentRunner(
        "a1", status, publish=published.append, send_command=lambda r, n: None,
        site_from_wall=lambda t: t,
    )  # fmt: skip


def test_spots_sent_with_a_pose_are_the_runners_frame_at_that_time() -> None:
    published: list[PoseUpdate] = []
    runner = _runner(published)
    est = PoseEstimate(
        5_000, 1.0, 2.0, 0.1, np.diag([1e-4, 1e-4, 1e-5]), "landmark", (1, 2), (1, 2, 3)
    )
    spots = np.array([[100.0, 200.0], [300.5, 240.25], [50.0, 60.0]])
    runner.receive(PoseMessage.from_estimate(1, est, 5_000, 6_000, spots))
    runner.receive(PoseMessage.from_estimate(2, est, 9_000, 9_500))  # no spots with this one
    frame = runner.frame_at(5_000)
    assert isinstance(frame, SpotsObserved)
    np.testing.assert_allclose(frame.pixels, spots)
    assert runner.frame_at(9_000) is None
    assert published[0].expected_ids == (1, 2, 3)  # for upkeep's pairing
    back = published[0].estimate()
    assert back is not None and back.expected_ids == (1, 2, 3)
