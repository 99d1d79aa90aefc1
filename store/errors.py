"""Domain errors of the server's data layer and services (the HTTP layer maps them)."""

from __future__ import annotations


class NotFoundError(KeyError):
    """No such landmark, robot or key (HTTP 404)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "not found"


class ConflictError(ValueError):
    """The change clashes with what exists: duplicate ID or radio address (HTTP 409)."""


class UnavailableError(RuntimeError):
    """A service the request needs is not running (no radio, site stopped) (HTTP 503)."""
