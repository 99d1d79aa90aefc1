"""Localizer settings from a YAML or JSON file (`irloc replay --config FILE`), and the record
of what a replay ran with, written beside its output.

The file holds only what differs from the defaults, grouped as `LocalizerConfig` groups them
(docs/localizer.md):

    detection: {max_area_px: 1500, max_elongation: 4.0}
    motion: {accel_sigma_m_s2: 1.5}

A bad file raises `RecordingError` naming the file and the key (`detection.max_area_px`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from localizer.config import LocalizerConfig
from localizer.config_dict import ConfigError, config_from_dict, config_to_dict
from recording.reader import RecordingError, load_structured
from recording.start_pose import StartPose


def read_config_file(path: Path | str) -> tuple[LocalizerConfig, dict[str, Any]]:
    """The settings of a YAML (or JSON: a YAML subset) file -> (config, the file's contents).

    Raises:
        RecordingError: unreadable, not YAML/JSON, or a setting that is unknown or invalid
            (the message names the key and the value).
    """
    p = Path(path)
    data = load_structured(p, json.loads if p.suffix.lower() == ".json" else yaml.safe_load)
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise RecordingError(p, None, f"expected a mapping of settings, got {type(data).__name__}")
    if isinstance(data.get("localizer"), dict) and set(data) <= _RECORD_KEYS:
        data = data["localizer"]  # a replay's record (`write_settings_record`)
    try:
        return config_from_dict(data), data
    except ConfigError as exc:
        raise RecordingError(p, None, str(exc)) from None


_RECORD_KEYS = {"recording", "config_file", "start_pose", "start_pose_source", "localizer"}


def settings_record_path(out: Path) -> Path:
    """Where the record of a replay's settings goes: `poses.csv` -> `poses.settings.yaml`."""
    return out.with_name(out.stem + ".settings.yaml")


def write_settings_record(
    out: Path,
    *,
    recording: Path,
    config: LocalizerConfig,
    start_pose: StartPose | None,
    start_pose_source: str,
    config_file: Path | None,
) -> Path:
    """Write what a replay ran with (every setting, defaults included, and the start pose)
    beside its output; returns the record's path. Read back with `read_config_file`: its
    `localizer` section is a settings file."""
    record = {
        "recording": str(recording),
        "config_file": None if config_file is None else str(config_file),
        "start_pose": None if start_pose is None else start_pose.as_dict(),
        "start_pose_source": start_pose_source,
        "localizer": config_to_dict(config),
    }
    path = settings_record_path(out)
    path.write_text(yaml.safe_dump(record, sort_keys=False), encoding="utf-8")
    return path
