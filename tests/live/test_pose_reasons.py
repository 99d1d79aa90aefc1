"""A robot's reasons: the latest, the poses per reason, and the lost event's reason."""

from __future__ import annotations

import numpy as np

from live.pose_reasons import ReasonTally, mode_change_event
from live.poses import PoseUpdate


def test_the_tally_keeps_the_latest_reason_and_counts_poses_per_reason() -> None:
    t = ReasonTally()
    cov = np.eye(3) * 1e-4
    t.note(PoseUpdate("r1", 1, "identifying", reason="waiting_for_radio", reason_text="w"))
    t.note(PoseUpdate("r1", 2, "landmark", 0.0, 0.0, 0.0, cov, quality=1.0, deviation_m=0.01))
    for k in range(3):
        t.note(PoseUpdate("r1", 3 + k, "dead_reckoning", 0.0, 0.0, 0.0, cov, quality=0.5,
                          reason="landmarks_dark", reason_text="dark"))  # fmt: skip
    assert (t.reason, t.reason_text, t.quality) == ("landmarks_dark", "dark", 0.5)
    assert t.counts() == {"waiting_for_radio": 1, "landmark_fix": 1, "landmarks_dark": 3}


def test_the_lost_event_names_the_reason() -> None:
    t = ReasonTally()
    t.note(PoseUpdate("r1", 1, "lost", 0.0, 0.0, 0.0, np.eye(3), reason="kidnapped_suspected",
                      reason_text="the landmarks seen disagree with the pose"))  # fmt: skip
    kind, message, data = mode_change_event("r1", "dead_reckoning", "lost", t) or ("", "", {})
    assert kind == "robot_lost"
    assert message == "robot r1 is lost: the landmarks seen disagree with the pose"
    assert data == {"reason": "kidnapped_suspected"}
    assert mode_change_event("r1", "lost", "landmark", t) == (
        "robot_localized", "robot r1 localized", {}
    )  # fmt: skip
    assert mode_change_event("r1", "landmark", "dead_reckoning", t) is None
