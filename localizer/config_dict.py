"""`LocalizerConfig` from and to plain dicts (a YAML or JSON settings file's contents).

Pure: the caller reads the file. Every key is checked against the dataclasses: an unknown
key, a value of the wrong type or one a sub-config's own check refuses raises `ConfigError`
naming the key by its dotted path (`fusion.pixel_sigma_px`) and the bad value. Keys left out
keep their defaults, so a file holds only what it changes; a retired key (`RETIRED`) that an
older settings file still names is ignored:

    detection: {max_area_px: 2000, max_elongation: 4}
    tracking: {sigma_gate: 3.5}
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from typing import Any, Literal, TypeVar, Union, get_args, get_origin

from localizer.config import LocalizerConfig

T = TypeVar("T")


class ConfigError(ValueError):
    """A settings value that cannot be used.

    Attributes:
        key: the dotted path of the bad key (empty for the whole document).
    """

    def __init__(self, key: str, what: str) -> None:
        self.key = key
        super().__init__(f"{key}: {what}" if key else what)


def config_from_dict(data: Mapping[str, object] | None) -> LocalizerConfig:
    """The `LocalizerConfig` a settings document describes (missing keys: defaults).

    Raises:
        ConfigError: an unknown key, a wrong type or a refused value, naming the key.
    """
    if data is None:
        return LocalizerConfig()
    return _build(LocalizerConfig, data, "")


def config_to_dict(config: object) -> dict[str, Any]:
    """Every field of a config dataclass as plain Python (tuples as lists), nested."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(config):  # type: ignore[arg-type]
        v = getattr(config, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = config_to_dict(v)
        elif isinstance(v, tuple):
            out[f.name] = list(v)
        elif isinstance(v, dict):
            out[f.name] = dict(v)
        else:
            out[f.name] = v
    return out


# Settings retired from the config and ignored where a settings file still names them
# (`irloc replay` writes every setting beside its poses): dotted path -> why.
RETIRED: dict[str, str] = {
    "fusion.full_frame_every_s": "no step of the localizer read it",
}


def _build(cls: type[T], data: object, path: str) -> T:
    if not isinstance(data, Mapping):
        raise ConfigError(path, f"expected a mapping of settings, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    kwargs: dict[str, object] = {}
    for key, value in data.items():
        where = f"{path}.{key}" if path else str(key)
        if where in RETIRED:
            continue
        if key not in fields:
            known = ", ".join(sorted(fields))
            raise ConfigError(where, f"unknown setting (known here: {known})")
        kind = hints[key]
        if dataclasses.is_dataclass(kind) and isinstance(kind, type):
            kwargs[key] = _build(kind, value, where)
        else:
            kwargs[key] = _coerce(kind, value, where)
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:
        raise ConfigError(path or cls.__name__, str(exc)) from None


def _coerce(kind: object, value: object, where: str) -> object:
    """`value` checked against the annotation `kind` (floats take ints, tuples lists)."""
    origin = get_origin(kind)
    if origin in (Union, types.UnionType):
        options = get_args(kind)
        if value is None and type(None) in options:
            return None
        for option in options:
            if option is type(None):
                continue
            try:
                return _coerce(option, value, where)
            except ConfigError:
                continue
        raise ConfigError(where, f"expected {_name(kind)}, got {value!r}")
    if origin is Literal:
        if value in get_args(kind):
            return value
        raise ConfigError(where, f"expected one of {list(get_args(kind))}, got {value!r}")
    if origin is tuple:
        args = get_args(kind)
        if not isinstance(value, list | tuple) or len(value) != len(args):
            raise ConfigError(where, f"expected a list of {len(args)} values, got {value!r}")
        pairs = enumerate(zip(args, value, strict=True))
        return tuple(_coerce(a, v, f"{where}[{i}]") for i, (a, v) in pairs)
    if origin is dict:
        key_kind, value_kind = get_args(kind)
        if not isinstance(value, Mapping):
            raise ConfigError(where, f"expected a mapping, got {value!r}")
        return {
            _coerce(key_kind, k, f"{where}.{k}"): _coerce(value_kind, v, f"{where}.{k}")
            for k, v in value.items()
        }
    if kind is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(where, f"expected true or false, got {value!r}")
    if kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(where, f"expected an integer, got {value!r}")
    if kind is float:
        if isinstance(value, int | float) and not isinstance(value, bool):
            if not math.isfinite(float(value)):
                raise ConfigError(where, f"expected a finite number, got {value!r}")
            return float(value)
        raise ConfigError(where, f"expected a number, got {value!r}")
    if kind is str:
        if isinstance(value, str):
            return value
        raise ConfigError(where, f"expected a string, got {value!r}")
    raise ConfigError(where, f"settings of type {_name(kind)} cannot be read from a file")


def _name(kind: object) -> str:
    return getattr(kind, "__name__", None) or str(kind).replace("typing.", "")


__all__ = ["ConfigError", "config_from_dict", "config_to_dict"]
