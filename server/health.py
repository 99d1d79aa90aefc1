"""The site's health at a glance (`/healthz` and the home page).

`/healthz` answers 200 `"status": "ok"` when all is well, and 503 `"status": "degraded"`
with `problems` naming what is wrong: the database does not answer (a `SELECT 1` within
`DB_TIMEOUT_S`) or cannot store events, a site thread is not running, a robot fed by the
site localizes no frame (`live.supervisor`).
"""

from __future__ import annotations

import asyncio
import weakref

from pydantic import BaseModel, Field
from sqlalchemy import Engine, create_engine, text
from sqlalchemy.pool import NullPool

from live.services import SiteServices

DB_TIMEOUT_S = 2.0


class Health(BaseModel):
    status: str
    robots: int
    landmarks: int
    radio: str
    problems: list[str] = Field(default_factory=list)


def site_problems(s: SiteServices) -> list[str]:
    """What the live site and the event writer report wrong (no database query)."""
    out: list[str] = []
    if s.runner is not None:
        out += s.runner.supervisor.problems()
    if s.events.writer.problem is not None:
        out.append(s.events.writer.problem)
    return out


_PROBES: weakref.WeakKeyDictionary[SiteServices, Engine] = weakref.WeakKeyDictionary()


def _probe_engine(s: SiteServices) -> Engine:
    """An engine of its own for the `SELECT 1` (no pool: a fresh connection each time, so a
    database that went away is seen; the site's engine and its statistics untouched)."""
    engine = _PROBES.get(s)
    if engine is None:
        url = s.settings.db_url
        args = {"timeout": DB_TIMEOUT_S} if url.startswith("sqlite") else {}
        engine = _PROBES[s] = create_engine(url, poolclass=NullPool, connect_args=args)
    return engine


def _select_one(s: SiteServices) -> None:
    with _probe_engine(s).connect() as conn:
        conn.execute(text("SELECT 1"))


async def database_problem(s: SiteServices) -> str | None:
    """None when the database answers a query within `DB_TIMEOUT_S`, else what failed."""
    try:
        await asyncio.wait_for(asyncio.to_thread(_select_one, s), DB_TIMEOUT_S)
    except TimeoutError:
        return f"database unavailable: no answer in {DB_TIMEOUT_S:g} s"
    except Exception as exc:
        first = str(getattr(exc, "orig", None) or exc).splitlines()[0][:160]
        return f"database unavailable: {first}"
    return None


def site_health(s: SiteServices, problems: list[str] | None = None) -> Health:
    """Robots and landmarks known, the radio link's state ("absent" without a radio), and
    `problems` (default: `site_problems`, without the database query)."""
    found = site_problems(s) if problems is None else problems
    return Health(
        status="degraded" if found else "ok",
        robots=len(s.robots.names()),
        landmarks=s.map.count(),
        radio=s.leds.radio_state,
        problems=found,
    )


async def check_health(s: SiteServices) -> Health:
    """`site_health` with the database queried too."""
    problems = site_problems(s)
    db = await database_problem(s)
    if db is not None and not any(p.startswith("database unavailable") for p in problems):
        problems.insert(0, db)
    return site_health(s, problems)
