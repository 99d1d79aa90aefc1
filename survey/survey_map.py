"""The map a survey starts from and the map it writes.

Input: map.json as everywhere (`docs/recording.md`), except that a landmark to be surveyed may
have a rough position (tape measure, floor plan) or none (`x`, `y`, `z` absent or null).
Output: the same objects with refined `x`, `y`, `z` (metres) and `sigma_m`, the 1-sigma
uncertainty of the position (the largest semi-axis of its ellipsoid); every other key of a
landmark (its `radio` address, say) is kept.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from localizer.types import FloatArray
from survey.result import SurveyResult


@dataclass(frozen=True, eq=False)
class SurveyLandmark:
    """One landmark of the input map: its ID, position if any (3,), and the object as read."""

    id: int
    position: FloatArray | None
    record: dict[str, Any]


def parse_survey_map(data: object, *, source: str) -> list[SurveyLandmark]:
    """map.json's parsed content -> landmarks; ValueError names `source`, index and key."""
    if not isinstance(data, dict) or not isinstance(data.get("landmarks"), list):
        raise ValueError(f"{source}: expected an object with a 'landmarks' list")
    out: list[SurveyLandmark] = []
    seen: set[int] = set()
    for i, rec in enumerate(data["landmarks"]):
        where = f"{source}: landmarks[{i}]"
        if not isinstance(rec, dict):
            raise ValueError(f"{where}: expected an object")
        lid = rec.get("id")
        if isinstance(lid, bool) or not isinstance(lid, int):
            raise ValueError(f"{where}: 'id' must be an integer, got {lid!r}")
        if lid in seen:
            raise ValueError(f"{where}: duplicate landmark id {lid}")
        seen.add(lid)
        coords = [rec.get(k) for k in ("x", "y", "z")]
        if all(c is None for c in coords):
            out.append(SurveyLandmark(lid, None, dict(rec)))
            continue
        for key, c in zip("xyz", coords, strict=True):
            if isinstance(c, bool) or not isinstance(c, int | float) or not math.isfinite(c):
                raise ValueError(
                    f"{where}: '{key}' must be a number of metres (or leave x, y, z all "
                    f"out for a landmark with no position yet), got {c!r}"
                )
        out.append(SurveyLandmark(lid, np.array(coords, dtype=np.float64), dict(rec)))
    return out


def read_survey_map(path: Path) -> list[SurveyLandmark]:
    """Read map.json; ValueError names the file and what is wrong."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: missing") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: cannot read it as JSON ({exc})") from None
    return parse_survey_map(data, source=str(path))


def surveyed_map(landmarks: list[SurveyLandmark], result: SurveyResult) -> dict[str, Any]:
    """The output map: every input landmark, surveyed ones with new x, y, z and sigma_m."""
    out: list[dict[str, Any]] = []
    for lm in landmarks:
        rec = dict(lm.record)
        est = result.landmarks.get(lm.id)
        if est is not None:
            x, y, z = (round(float(v), 5) for v in est.position)
            rec.update(x=x, y=y, z=z, sigma_m=round(est.sigma_m, 5))
            if est.flags:
                rec["survey_flags"] = list(est.flags)
        out.append(rec)
    return {"landmarks": out}


def write_map_atomic(path: Path, content: dict[str, Any]) -> None:
    """Write JSON to `path` through a temporary file in its folder (never half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(content, fh, indent=2)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
