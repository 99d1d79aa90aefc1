"""Fixtures of the data layer's tests: a database URL in a fresh temporary folder."""

from __future__ import annotations

from tests.server.conftest import db_url

__all__ = ["db_url"]
