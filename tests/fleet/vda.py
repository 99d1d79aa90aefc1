"""Validation against the official VDA 5050 2.1.0 JSON schemas (shared/data/vda5050)."""

from __future__ import annotations

import json
from datetime import datetime
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema
import pytest

SCHEMA_DIRS = (
    Path(__file__).resolve().parents[3] / "shared" / "data" / "vda5050" / "2.1.0",
    Path("/work/shared/data/vda5050/2.1.0"),
)


@cache
def _validator(topic: str) -> jsonschema.Draft202012Validator:
    for d in SCHEMA_DIRS:
        path = d / f"{topic}.schema"
        if path.is_file():
            schema = json.loads(path.read_text(encoding="utf-8"))
            return jsonschema.Draft202012Validator(
                schema, format_checker=jsonschema.Draft202012Validator.FORMAT_CHECKER
            )
    pytest.skip(f"the VDA 5050 2.1.0 schema {topic}.schema is not in {SCHEMA_DIRS}")


def validate_vda(topic: str, message: dict[str, Any]) -> None:
    """Raise jsonschema.ValidationError when `message` is not a valid `topic` message (and
    ValueError for a `timestamp` that is not ISO 8601 UTC: jsonschema checks `date-time`
    only with an optional package)."""
    _validator(topic).validate(message)
    stamp = message.get("timestamp")
    if stamp is not None and not (
        stamp.endswith("Z") and datetime.fromisoformat(stamp.replace("Z", "+00:00"))
    ):
        raise ValueError(f"timestamp {stamp!r} is not ISO 8601 UTC")
