"""VDA 5050 v2.1 messages (fleet/vda5050.py) against the official JSON schemas."""

from __future__ import annotations

import math

import jsonschema
import numpy as np
import pytest

from fleet.vda5050 import HeaderIds, connection_message, visualization_message
from localizer.events import MODES
from tests.fleet.vda import validate_vda

WALL = 1_700_000_000_123_456_789


@pytest.mark.parametrize("mode", MODES)
def test_visualization_validates_in_every_mode(mode: str) -> None:
    pose = None if mode == "identifying" else (1.5, -2.0, math.pi)
    msg = visualization_message(
        3, WALL, "irloc", "r1", map_id="hall", mode=mode, pose=pose,  # type: ignore[arg-type]
        covariance=np.diag([4e-4, 1e-4, 1e-5]) if pose else None,
        quality=0.42 if pose else None,
    )  # fmt: skip
    validate_vda("visualization", msg)
    assert msg["version"] == "2.1.0" and msg["timestamp"] == "2023-11-14T22:13:20.123Z"
    if pose is None:
        assert "agvPosition" not in msg
    else:
        pos = msg["agvPosition"]
        assert pos["positionInitialized"] is (mode in ("landmark", "dead_reckoning"))
        # the 95 % circle of sigmas (2, 1) cm: 2.0358 x the major sigma (pose_quality)
        assert pos["deviationRange"] == pytest.approx(0.02 * 2.035793, rel=1e-3)
        assert pos["localizationScore"] == 0.42


def test_the_pose_s_own_radius_and_a_clipped_score() -> None:
    msg = visualization_message(
        0, WALL, "irloc", "r1", map_id="m", mode="dead_reckoning", pose=(0, 0, 0),
        covariance=np.eye(3), quality=1.0000001, deviation_m=0.1234567,
    )  # fmt: skip
    validate_vda("visualization", msg)
    assert msg["agvPosition"]["deviationRange"] == 0.1235
    assert msg["agvPosition"]["localizationScore"] == 1.0


@pytest.mark.parametrize("state", ["ONLINE", "OFFLINE", "CONNECTIONBROKEN"])
def test_connection_validates(state: str) -> None:
    validate_vda("connection", connection_message(0, WALL, "irloc", "r1", state))  # type: ignore[arg-type]


def test_the_schema_catches_a_wrong_message() -> None:
    bad = connection_message(0, WALL, "irloc", "r1", "ONLINE")
    bad["connectionState"] = "MAYBE"
    with pytest.raises(jsonschema.ValidationError):
        validate_vda("connection", bad)
    no_map = visualization_message(
        0, WALL, "irloc", "r1", map_id="m", mode="landmark", pose=(0, 0, 0)
    )
    del no_map["agvPosition"]["mapId"]
    with pytest.raises(jsonschema.ValidationError, match="mapId"):
        validate_vda("visualization", no_map)


def test_header_ids_count_per_robot_and_topic() -> None:
    h = HeaderIds()
    assert [h.take("r1", "visualization") for _ in range(3)] == [0, 1, 2]
    assert h.take("r1", "connection") == 0 and h.take("r2", "visualization") == 0
