"""API keys: created with a role, stored only as a SHA-256 hash of a 256-bit random token.

A high-entropy token needs no slow hash (nothing to brute-force); lookups are by hash, and a
small in-memory cache keeps the per-request check off the database. A key's `last_used_at`
is written at most once per `touch_interval_s` (a minute) per key, on a background thread.
"""

from __future__ import annotations

import builtins
import concurrent.futures
import hashlib
import logging
import secrets
import threading
import time
from collections.abc import Callable
from datetime import datetime

from sqlalchemy import Engine
from sqlmodel import Session, col, select, update

from server.errors import NotFoundError
from server.models import ROLES, ApiKey, ApiKeyPublic, Role, utcnow

TOKEN_PREFIX = "irloc_"


def hash_key(token: str) -> str:
    """sha256 of the key, hex."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


log = logging.getLogger(__name__)
TOUCH_INTERVAL_S = 60.0


class KeyStore:
    """Create, check and revoke API keys; record when each was last used.

    Args:
        engine: the database.
        touch_interval_s: at most one `last_used_at` write per key in this time, seconds.
        clock: monotonic seconds (for the throttle).
    """

    def __init__(
        self,
        engine: Engine,
        *,
        touch_interval_s: float = TOUCH_INTERVAL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.engine = engine
        self.touch_interval_s = touch_interval_s
        self.clock = clock
        self.touches = 0
        self._cache: dict[str, tuple[int, Role]] = {}
        self._lock = threading.Lock()
        self._touched: dict[int, float] = {}
        self._writer = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="key-touch")

    def create(self, role: str, name: str = "") -> tuple[str, ApiKeyPublic]:
        """A new key of `role`; returns (the key, shown only now; its record)."""
        if role not in ROLES:
            raise ValueError(f"role: expected one of {', '.join(ROLES)}, got {role!r}")
        token = TOKEN_PREFIX + secrets.token_urlsafe(32)
        row = ApiKey(
            name=name, role=role, prefix=token[: len(TOKEN_PREFIX) + 6], hash=hash_key(token)
        )
        with Session(self.engine) as s:
            s.add(row)
            s.commit()
            s.refresh(row)
            return token, ApiKeyPublic.model_validate(row, from_attributes=True)

    def role_of(self, token: str) -> tuple[int, Role] | None:
        """(key id, role) of a valid, unrevoked key; None otherwise."""
        digest = hash_key(token)
        hit = self._cache.get(digest) or self._lookup(digest)
        if hit is None:
            return None
        self._touch(hit[0])
        return hit

    def _lookup(self, digest: str) -> tuple[int, Role] | None:
        with Session(self.engine) as s:
            row = s.exec(select(ApiKey).where(ApiKey.hash == digest)).first()
            if row is None or row.revoked or row.id is None:
                return None
            out: tuple[int, Role] = (row.id, row.role)  # type: ignore[assignment]
        with self._lock:
            self._cache[digest] = out
        return out

    def _touch(self, key_id: int) -> None:
        """Note that `key_id` was used now: a database write unless one was made for it less
        than `touch_interval_s` ago (the write runs on a background thread)."""
        now = self.clock()
        with self._lock:
            last = self._touched.get(key_id)
            if last is not None and now - last < self.touch_interval_s:
                return
            self._touched[key_id] = now
            self.touches += 1
            self._writer.submit(self._write_last_used, key_id, utcnow())

    def _write_last_used(self, key_id: int, when: datetime) -> None:
        try:
            with Session(self.engine) as s:
                s.exec(update(ApiKey).where(col(ApiKey.id) == key_id).values(last_used_at=when))
                s.commit()
        except Exception:  # a busy or closed database: the next use tries again
            log.warning("could not record the use of API key %d", key_id, exc_info=True)
            with self._lock:
                self._touched.pop(key_id, None)

    def flush(self) -> None:
        """Wait for the pending `last_used_at` writes."""
        self._writer.submit(lambda: None).result()

    def close(self) -> None:
        """Finish the pending writes and stop the writer thread."""
        self._writer.shutdown(wait=True)

    def list(self) -> builtins.list[ApiKeyPublic]:
        """Every key (never the key itself), with when it was last used (to the minute)."""
        self.flush()
        with Session(self.engine) as s:
            return [
                ApiKeyPublic.model_validate(r, from_attributes=True)
                for r in s.exec(select(ApiKey).order_by(col(ApiKey.id)))
            ]

    def revoke(self, key_id: int) -> None:
        with Session(self.engine) as s:
            row = s.get(ApiKey, key_id)
            if row is None:
                raise NotFoundError(f"API key {key_id} does not exist")
            row.revoked = True
            s.add(row)
            s.commit()
        with self._lock:
            self._cache = {h: v for h, v in self._cache.items() if v[0] != key_id}

    def has_admin(self) -> bool:
        with Session(self.engine) as s:
            q = select(ApiKey).where(ApiKey.role == "admin", ApiKey.revoked == False)  # noqa: E712
            return s.exec(q).first() is not None

    def ensure_admin(self) -> str | None:
        """Create the first admin key when there is none; returns it (once) or None."""
        if self.has_admin():
            return None
        token, _ = self.create("admin", name="first admin")
        return token
