"""Fixtures: the app on a real SQLite file in a temporary folder, keys of every role."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

with warnings.catch_warnings():
    # starlette 1.x warns that its TestClient will move from httpx to httpx2; not our concern
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from fastapi import FastAPI

from live.services import SiteServices
from live.settings import Settings
from server.main import create_app


@dataclass
class Api:
    """A started app, its services and a header per role."""

    client: TestClient
    services: SiteServices
    keys: dict[str, str]

    def h(self, role: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.keys[role]}"}

    def wait_for(
        self,
        path: str,
        until: Callable[[dict[str, Any]], bool],
        timeout_s: float,
        *,
        role: str = "admin",
        every_s: float = 0.1,
    ) -> dict[str, Any]:
        """GET `path` until its JSON satisfies `until`; AssertionError with the last answer."""
        deadline = time.monotonic() + timeout_s
        st: dict[str, Any] = {}
        while time.monotonic() < deadline:
            st = self.client.get(path, headers=self.h(role)).json()
            if until(st):
                return st
            time.sleep(every_s)
        raise AssertionError(f"{path} did not get there in {timeout_s} s: {st}")


def make_test_app(data_dir: Path, **settings: object) -> FastAPI:
    """The app of a test: no viewer, no battery polls, `settings` on top."""
    conf = {"data_dir": data_dir, "viewer_enabled": False, "battery_interval_s": None}
    conf.update(settings)
    return create_app(Settings(**conf))  # type: ignore[arg-type]


def role_keys(services: SiteServices) -> dict[str, str]:
    """The first admin key of a fresh data folder and a new key of each other role."""
    admin = services.initial_admin_key
    assert admin is not None, "expected a fresh data folder"
    keys = {"admin": admin}
    for role in ("operator", "viewer"):
        keys[role], _ = services.keys.create(role, name=f"test {role}")
    return keys


def demo_with_robots(path: Path, robots: Collection[str]) -> Path:
    """The demo scenario with only `robots` of its three (same world, so the same map and
    landmarks), written to `path` for `Settings.scenario`: a live test that watches some
    robots leaves out the others, whose cameras and localizers would take CPU from it."""
    import sim.scenarios

    demo = yaml.safe_load((Path(sim.scenarios.__file__).parent / "demo.yaml").read_text())
    demo["robots"] = [r for r in demo["robots"] if r["name"] in robots]
    assert {r["name"] for r in demo["robots"]} == set(robots), robots
    path.write_text(yaml.safe_dump(demo))
    return path


def start_api(data_dir: Path, **settings: object) -> Iterator[Api]:
    app = make_test_app(data_dir, **settings)
    with TestClient(app) as client:
        services: SiteServices = app.state.services
        yield Api(client, services, role_keys(services))


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    """The database of a test: a SQLite file in its temporary folder (tests/server/
    test_postgres.py overrides this with a fresh PostgreSQL database)."""
    return f"sqlite:///{tmp_path / 'irloc.db'}"


@pytest.fixture
def api(tmp_path: Path, db_url: str) -> Iterator[Api]:
    """The API without a live site (database, auth, map, streams)."""
    yield from start_api(tmp_path, site_enabled=False, database_url=db_url)


LM = {"id": 11, "x": 0.6, "y": 0.3, "z": 2.5, "radio": "0013A20041B2C3D4"}
