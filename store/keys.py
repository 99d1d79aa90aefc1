"""API keys: created with a role, stored only as a SHA-256 hash of a 256-bit random token.

A high-entropy token needs no slow hash (nothing to brute-force); lookups are by hash. A
small in-memory cache keeps the per-request check off the database: a valid key is trusted
for `cache_ttl_s` (0.5 s, so a key revoked by `irloc keys revoke` in another process stops
working within that time), an unknown or revoked one is remembered for `negative_ttl_s` (so
the same bad key reaches the database once). `role_of_async` looks keys up on a worker thread
(never on the event loop), one lookup per key however many requests wait for it. A key's
`last_used_at` is written at most once per `touch_interval_s` (a minute) per key, on a
background thread.
"""

from __future__ import annotations

import asyncio
import builtins
import concurrent.futures
import hashlib
import logging
import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from datetime import datetime
from typing import Literal

from sqlalchemy import Engine
from sqlmodel import Session, col, select, update

from store.errors import NotFoundError
from store.models import ROLES, ApiKey, ApiKeyPublic, Role, utcnow

TOKEN_PREFIX = "irloc_"


def hash_key(token: str) -> str:
    """sha256 of the key, hex."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


log = logging.getLogger(__name__)
TOUCH_INTERVAL_S = 60.0
CACHE_TTL_S = 0.5
NEGATIVE_TTL_S = 300.0
NEGATIVE_MAX = 100_000
Found = tuple[int, Role]


class KeyStore:
    """Create, check and revoke API keys; record when each was last used.

    Args:
        engine: the database.
        touch_interval_s: at most one `last_used_at` write per key in this time, seconds.
        cache_ttl_s: a valid key is trusted this long without asking the database, seconds
            (the delay before a revocation by another process takes effect).
        negative_ttl_s: an unknown or revoked key is refused this long without asking the
            database again, seconds (at most `NEGATIVE_MAX` remembered, oldest forgotten).
        clock: monotonic seconds (for the throttle and the caches).

    Attributes:
        lookups: database lookups made; lookup_threads: names of the threads they ran on.
    """

    def __init__(
        self,
        engine: Engine,
        *,
        touch_interval_s: float = TOUCH_INTERVAL_S,
        cache_ttl_s: float = CACHE_TTL_S,
        negative_ttl_s: float = NEGATIVE_TTL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.engine = engine
        self.touch_interval_s = touch_interval_s
        self.cache_ttl_s = cache_ttl_s
        self.negative_ttl_s = negative_ttl_s
        self.clock = clock
        self.touches = 0
        self.lookups = 0
        self.lookup_threads: set[str] = set()
        self._cache: dict[str, tuple[Found, float]] = {}
        self._negative: OrderedDict[str, float] = OrderedDict()
        self._inflight: dict[str, asyncio.Future[Found | None]] = {}
        self._revoked: set[int] = set()
        self._lock = threading.Lock()
        self._touched: dict[int, float] = {}
        self._writer = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="key-touch")
        self._readers = concurrent.futures.ThreadPoolExecutor(2, thread_name_prefix="key-lookup")

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

    def cached(self, token: str) -> Found | Literal[False] | None:
        """What the caches know of `token` without the database: (key id, role) of a valid
        key, None for a key known to be bad, False when only the database can tell."""
        digest = hash_key(token)
        now = self.clock()
        with self._lock:
            hit = self._cache.get(digest)
            if hit is not None and now < hit[1] and hit[0][0] not in self._revoked:
                found = hit[0]
            elif (until := self._negative.get(digest)) is not None and now < until:
                return None
            else:
                return False
        self._touch(found[0])
        return found

    def role_of(self, token: str) -> Found | None:
        """(key id, role) of a valid, unrevoked key; None otherwise (may read the database
        on the calling thread: on the event loop use `role_of_async`)."""
        known = self.cached(token)
        if known is not False:
            return known
        found = self._lookup(hash_key(token))
        if found is not None:
            self._touch(found[0])
        return found

    async def role_of_async(self, token: str) -> Found | None:
        """`role_of` for the event loop: a database lookup runs on a worker thread, and
        concurrent checks of the same key share one lookup."""
        known = self.cached(token)
        if known is not False:
            return known
        digest = hash_key(token)
        pending = self._inflight.get(digest)
        if pending is None:
            loop = asyncio.get_running_loop()
            pending = asyncio.ensure_future(
                loop.run_in_executor(self._readers, self._lookup, digest)
            )
            self._inflight[digest] = pending
            pending.add_done_callback(lambda _: self._inflight.pop(digest, None))
        found = await asyncio.shield(pending)
        if found is not None:
            self._touch(found[0])
        return found

    def _lookup(self, digest: str) -> Found | None:
        with self._lock:
            self.lookups += 1
            self.lookup_threads.add(threading.current_thread().name)
        with Session(self.engine) as s:
            row = s.exec(select(ApiKey).where(ApiKey.hash == digest)).first()
            valid = row is not None and not row.revoked and row.id is not None
            out: Found | None = (row.id, row.role) if valid else None  # type: ignore[union-attr,assignment]
        now = self.clock()
        with self._lock:
            if out is None:
                self._cache.pop(digest, None)
                self._negative[digest] = now + self.negative_ttl_s
                self._negative.move_to_end(digest)
                while len(self._negative) > NEGATIVE_MAX:
                    self._negative.popitem(last=False)
            else:
                self._cache[digest] = (out, now + self.cache_ttl_s)
        return out

    def is_revoked_here(self, key_id: int) -> bool:
        """Whether this store revoked `key_id` (no database: for streams that poll)."""
        return key_id in self._revoked

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
        """Finish the pending writes and stop the writer and lookup threads."""
        self._writer.shutdown(wait=True)
        self._readers.shutdown(wait=True)

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
            self._revoked.add(key_id)
            self._cache = {h: v for h, v in self._cache.items() if v[0][0] != key_id}

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
