from __future__ import annotations

import json
from pathlib import Path

import pytest

from rf_gateway.emulator_cli import remotes_from_map


def test_remotes_come_from_the_map_radios(tmp_path: Path) -> None:
    path = tmp_path / "map.json"
    path.write_text(
        json.dumps(
            {
                "landmarks": [
                    {"id": 11, "x": 0, "y": 0, "z": 2.5, "radio": "0013a20041000011"},
                    {"id": 12, "x": 1, "y": 0, "z": 2.5},
                ]
            }
        )
    )
    remotes = remotes_from_map(path)
    assert [(r.address, r.node_id) for r in remotes] == [("0013A20041000011", "LM11")]


def test_bad_map_and_bad_radio_are_named(tmp_path: Path) -> None:
    path = tmp_path / "map.json"
    path.write_text("{}")
    with pytest.raises(ValueError, match=r"map\.json: not a map\.json"):
        remotes_from_map(path)
    path.write_text(json.dumps({"landmarks": [{"id": 3, "radio": "42"}]}))
    with pytest.raises(ValueError, match=r"landmark #0 \(id 3\) radio"):
        remotes_from_map(path)
