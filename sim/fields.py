"""Reading user-written YAML with errors that name the file and the field's path
(e.g. "site.yaml: robots[1].route.waypoints[2]: expected [x, y], got 'a'").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


class Node:
    """A value of a parsed YAML document and its path in it."""

    def __init__(self, value: Any, path: str, source: str) -> None:
        self.value = value
        self.path = path
        self.source = source

    def error(self, what: str) -> ValueError:
        where = f"{self.source}: {self.path}" if self.path else self.source
        return ValueError(f"{where}: {what}")

    def _child_path(self, key: str | int) -> str:
        if isinstance(key, int):
            return f"{self.path}[{key}]"
        return f"{self.path}.{key}" if self.path else key

    def mapping(self, allowed: tuple[str, ...]) -> Node:
        """Check this is a mapping with no keys outside `allowed` (typos are errors)."""
        if not isinstance(self.value, Mapping):
            raise self.error(f"expected a mapping, got {self.value!r}")
        unknown = sorted(str(k) for k in self.value if k not in allowed)
        if unknown:
            raise self.error(f"unknown field(s) {unknown}; allowed: {sorted(allowed)}")
        return self

    def has(self, key: str) -> bool:
        return isinstance(self.value, Mapping) and self.value.get(key) is not None

    def child(self, key: str, default: Any = None, *, required: bool = False) -> Node:
        if not self.has(key):
            if required:
                raise self.error(f"missing field '{key}'")
            return Node(default, self._child_path(key), self.source)
        return Node(self.value[key], self._child_path(key), self.source)

    def items(self) -> list[Node]:
        """The elements of a list (an absent value is an empty list)."""
        if self.value is None:
            return []
        if not isinstance(self.value, list):
            raise self.error(f"expected a list, got {self.value!r}")
        return [Node(v, self._child_path(i), self.source) for i, v in enumerate(self.value)]

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        low: float = -math.inf,
        high: float = math.inf,
    ) -> float:
        """A finite number in [low, high]; `default` when absent (None: required)."""
        node = self.child(key, default, required=default is None)
        v = node.value
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise node.error(f"expected a number, got {v!r}")
        if not low <= v <= high:
            raise node.error(f"must be in [{low}, {high}], got {v!r}")
        return float(v)

    def integer(self, key: str, default: int | None = None, *, low: int = 0) -> int:
        node = self.child(key, default, required=default is None)
        v = node.value
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise node.error(f"expected an integer >= {low}, got {v!r}")
        return int(v)

    def string(self, key: str, default: str | None = None, *, choices: tuple[str, ...] = ()) -> str:
        node = self.child(key, default, required=default is None)
        v = node.value
        if not isinstance(v, str) or (choices and v not in choices):
            raise node.error(f"expected one of {list(choices)}" if choices else "expected text")
        return v

    def boolean(self, key: str, default: bool) -> bool:
        node = self.child(key, default)
        if not isinstance(node.value, bool):
            raise node.error(f"expected true or false, got {node.value!r}")
        return bool(node.value)

    def vector(self, n: int, what: str) -> tuple[float, ...]:
        """This value as a list of `n` finite numbers (`what` names it, e.g. "[x, y]")."""
        v = self.value
        ok = isinstance(v, list) and len(v) == n
        ok = ok and all(
            not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x) for x in v
        )
        if not ok:
            raise self.error(f"expected {what}, got {v!r}")
        return tuple(float(x) for x in v)

    def child_vector(
        self, key: str, n: int, what: str, default: tuple[float, ...] | None = None
    ) -> tuple[float, ...]:
        if not self.has(key):
            if default is None:
                raise self.error(f"missing field '{key}'")
            return default
        return self.child(key).vector(n, what)
