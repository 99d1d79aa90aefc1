"""API keys: created with a role, stored only as a SHA-256 hash of a 256-bit random token.

A high-entropy token needs no slow hash (nothing to brute-force); lookups are by hash, and a
small in-memory cache keeps the per-request check off the database.
"""

from __future__ import annotations

import builtins
import hashlib
import secrets
import threading

from sqlalchemy import Engine
from sqlmodel import Session, col, select

from server.errors import NotFoundError
from server.models import ROLES, ApiKey, ApiKeyPublic, Role

TOKEN_PREFIX = "irloc_"


def hash_key(token: str) -> str:
    """sha256 of the key, hex."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


class KeyStore:
    """Create, check and revoke API keys."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._cache: dict[str, tuple[int, Role]] = {}
        self._lock = threading.Lock()

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
        hit = self._cache.get(digest)
        if hit is not None:
            return hit
        with Session(self.engine) as s:
            row = s.exec(select(ApiKey).where(ApiKey.hash == digest)).first()
            if row is None or row.revoked or row.id is None:
                return None
            out: tuple[int, Role] = (row.id, row.role)  # type: ignore[assignment]
        with self._lock:
            self._cache[digest] = out
        return out

    def list(self) -> builtins.list[ApiKeyPublic]:
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
