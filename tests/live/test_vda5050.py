"""VDA 5050 visualization messages from pose updates (live/vda5050.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from live.poses import PoseUpdate
from live.vda5050 import (
    InitPosition,
    VisualizationEncoder,
    deviation_range_m,
    init_positions,
    iso8601_utc,
    visualization_topic,
)


def test_message_carries_the_pose_and_counts_headers_per_robot() -> None:
    enc = VisualizationEncoder("irloc", "hall-1")
    cov = np.diag([0.02**2, 0.01**2, 0.001**2])
    u = PoseUpdate(
        "r1", 5, "landmark", 1.5, -2.0, math.pi / 2, cov, (1, 2), 1_700_000_000_123_456_789
    )
    msg = enc.encode(u)
    assert msg["headerId"] == 0 and enc.encode(u)["headerId"] == 1
    assert enc.encode(PoseUpdate("r2", 5, "identifying"))["headerId"] == 0
    assert msg["timestamp"] == "2023-11-14T22:13:20.123Z"
    assert (msg["version"], msg["manufacturer"], msg["serialNumber"]) == ("2.1.0", "irloc", "r1")
    pos = msg["agvPosition"]
    assert (pos["x"], pos["y"], pos["theta"], pos["mapId"]) == (1.5, -2.0, math.pi / 2, "0")
    assert pos["positionInitialized"] is True
    # the 95 % circle of sigmas (2, 1) cm: 2.0358 x the major sigma (pose_quality)
    assert pos["deviationRange"] == pytest.approx(0.02 * 2.035793, rel=1e-3)
    assert "localizationScore" not in pos  # an update without a quality
    scored = enc.encode(PoseUpdate("r1", 7, "dead_reckoning", 0.0, 0.0, 0.0, cov, quality=0.5,
                                   deviation_m=0.3, reason="no_landmark_in_view"))  # fmt: skip
    assert scored["agvPosition"]["localizationScore"] == 0.5
    assert scored["agvPosition"]["deviationRange"] == 0.3
    json.dumps(msg)  # plain JSON types only


def test_no_position_before_the_first_fix_and_not_initialized_when_lost() -> None:
    enc = VisualizationEncoder("irloc", "hall-1")
    assert "agvPosition" not in enc.encode(PoseUpdate("r1", 5, "identifying"))
    lost = enc.encode(PoseUpdate("r1", 6, "lost", 1.0, 1.0, 0.0, np.eye(3)))
    assert lost["agvPosition"]["positionInitialized"] is False


def test_topic_and_helpers() -> None:
    assert visualization_topic("irloc", "r1") == "uagv/v2/irloc/r1/visualization"
    with pytest.raises(ValueError, match="serial number"):
        visualization_topic("irloc", "r/1")
    assert iso8601_utc(0) == "1970-01-01T00:00:00.000Z"
    assert deviation_range_m(np.zeros((3, 3))) == 0.0


def test_map_id_is_the_floor_of_the_pose() -> None:
    enc = VisualizationEncoder("irloc", "site")
    u = PoseUpdate("r1", 5, "landmark", 1.0, 2.0, 0.0, np.eye(3) * 1e-4, floor="1")
    assert enc.encode(u)["agvPosition"]["mapId"] == "1"


def test_init_position_actions_are_read_and_bad_ones_named() -> None:
    params = {"x": 8.0, "y": 2.4, "theta": 0.5, "mapId": "1", "lastNodeId": "lift-1"}
    assert init_positions([("initPosition", "a1", params)]) == [
        InitPosition("a1", "1", 8.0, 2.4, 0.5)
    ]
    with pytest.raises(ValueError, match="action 'a2': theta must be a number"):
        init_positions([("initPosition", "a2", {**params, "theta": "north"})])
    with pytest.raises(ValueError, match="action 'a3': mapId must name a floor"):
        init_positions([("initPosition", "a3", {"x": 1, "y": 2, "theta": 0})])
    with pytest.raises(ValueError, match="'startPause' is not supported"):
        init_positions([("startPause", "a4", {})])
