from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from localizer.landmark_map import DuplicateLandmarkError, LandmarkMap

RECORDS = [
    {"id": 11, "x": 0.6, "y": 0.3, "z": 2.5},
    {"id": 12, "x": 1.8, "y": 0.3, "z": 2.52, "radio": "0013A20041000001"},
    {"id": 7, "x": -1.2, "y": 4.0, "z": 2.48},
]


def test_records_round_trip_and_lookup() -> None:
    m = LandmarkMap.from_records(RECORDS)
    assert len(m) == 3
    assert 12 in m and 13 not in m
    assert m.index_of(7) == 2
    np.testing.assert_allclose(m.position(12), [1.8, 0.3, 2.52])
    np.testing.assert_array_equal(m.ids, [11, 12, 7])
    assert m.to_records() == [{k: r[k] for k in ("id", "x", "y", "z")} for r in RECORDS]
    with pytest.raises(ValueError):
        m.positions[0, 0] = 5.0  # read-only


def test_unknown_id_is_named() -> None:
    m = LandmarkMap.from_records(RECORDS)
    with pytest.raises(KeyError, match="unknown landmark id 99"):
        m.index_of(99)


def test_duplicate_ids_are_rejected_naming_the_id() -> None:
    records = [*RECORDS, {"id": 12, "x": 5.0, "y": 5.0, "z": 2.5}]
    with pytest.raises(DuplicateLandmarkError, match=r"map\.json: duplicate landmark id 12"):
        LandmarkMap.from_records(records, source="map.json")
    with pytest.raises(DuplicateLandmarkError, match="duplicate landmark id 4"):
        LandmarkMap(np.array([4, 5, 4]), np.zeros((3, 3)))
    assert issubclass(DuplicateLandmarkError, ValueError)


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ("not a dict", "landmark #3 is not an object"),
        ({"x": 1.0, "y": 1.0, "z": 2.5}, "landmark #3 has no 'id'"),
        ({"id": "13", "x": 1.0, "y": 1.0, "z": 2.5}, "landmark #3: 'id' must be an integer"),
        ({"id": True, "x": 1.0, "y": 1.0, "z": 2.5}, "'id' must be an integer, got True"),
        ({"id": 13, "x": 1.0, "z": 2.5}, "landmark 13: missing 'y'"),
        ({"id": 13, "x": 1.0, "y": "one", "z": 2.5}, "landmark 13: 'y' must be a finite number"),
        ({"id": 13, "x": 1.0, "y": 1.0, "z": float("nan")}, "landmark 13: 'z' must be a finite"),
        ({"id": 13, "x": 1.0, "y": 1.0, "z": float("inf")}, "'z' must be a finite number"),
        ({"id": 13, "x": False, "y": 1.0, "z": 2.5}, "landmark 13: 'x' must be a finite number"),
    ],
)
def test_bad_records_are_named(record: Any, message: str) -> None:
    with pytest.raises(ValueError, match=r"^site/map\.json: ") as err:
        LandmarkMap.from_records([*RECORDS, record], source="site/map.json")
    assert message in str(err.value)


def test_constructor_checks_shapes_and_values() -> None:
    with pytest.raises(ValueError, match="2 ids but 3 positions"):
        LandmarkMap(np.array([1, 2]), np.zeros((3, 3)))
    pos = np.zeros((2, 3))
    pos[1, 2] = np.nan
    with pytest.raises(ValueError, match="landmark 8 has a non-finite coordinate"):
        LandmarkMap(np.array([3, 8]), pos)


def test_empty_map() -> None:
    m = LandmarkMap.from_records([])
    assert len(m) == 0
    assert m.positions.shape == (0, 3)
    assert m.to_records() == []


def test_a_map_may_state_each_landmarks_sigma() -> None:
    m = LandmarkMap(np.array([1, 2]), np.zeros((2, 3)), np.array([0.001, np.nan]))
    assert m.sigma_at(0) == 0.001
    assert m.sigma_at(1) is None  # not stated
    assert LandmarkMap(np.array([1]), np.zeros((1, 3))).sigma_at(0) is None
    with pytest.raises(ValueError, match="2 ids but 1 sigmas"):
        LandmarkMap(np.array([1, 2]), np.zeros((2, 3)), np.array([0.001]))
    with pytest.raises(ValueError, match="negative or infinite"):
        LandmarkMap(np.array([1]), np.zeros((1, 3)), np.array([-0.001]))
