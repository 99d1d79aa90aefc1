"""Answers for a database or disk that fails under a request: 503 "database unavailable"
(the server is down, restarting or locked by another process: try again), 507 "disk full"
(no space left for the database or a file), never a 500 with a traceback.

Each such answer is counted (`/metrics`, `irloc_http_errors_total`) and logged once per
`LOG_EVERY_S` per kind with what failed, so an outage is one line in the log, not one per
request.
"""

from __future__ import annotations

import errno
import logging
import time

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from sqlalchemy.exc import InterfaceError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeoutError

log = logging.getLogger(__name__)
LOG_EVERY_S = 10.0
NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
_last_logged: dict[str, float] = {}


def is_disk_full(exc: BaseException) -> bool:
    """Whether `exc` (or what it wraps) says there is no space left."""
    seen: BaseException | None = exc
    for _ in range(5):
        if seen is None:
            return False
        if isinstance(seen, OSError) and seen.errno in NO_SPACE:
            return True
        if "database or disk is full" in str(seen) or "No space left" in str(seen):
            return True
        seen = getattr(seen, "orig", None) or seen.__cause__
    return False


def storage_answer(exc: BaseException) -> tuple[int, str] | None:
    """(status, detail) for a storage failure, None when `exc` is not one."""
    if is_disk_full(exc):
        said = exc.strerror if isinstance(exc, OSError) else None
        if said and "No space left" not in said:
            return 507, f"disk full: {said}"
        return 507, "disk full: no space left for the data (free some space; nothing was saved)"
    if isinstance(exc, OperationalError | InterfaceError | PoolTimeoutError):
        text = str(getattr(exc, "orig", None) or exc).splitlines()[0][:160]
        if "locked" in text or "busy" in text:
            return 503, f"database unavailable: busy (another process holds it: {text})"
        return 503, f"database unavailable: {text}"
    if isinstance(exc, OSError) and exc.errno in (errno.EIO, errno.EROFS, errno.EACCES):
        return 503, f"storage unavailable: {exc.strerror or exc}"
    return None


def _log_once(kind: str, detail: str, path: str) -> None:
    now = time.monotonic()
    if now - _last_logged.get(kind, -LOG_EVERY_S) >= LOG_EVERY_S:
        _last_logged[kind] = now
        log.error("%s (%s; such answers are logged once per %g s)", detail, path, LOG_EVERY_S)


def install_storage_errors(app: FastAPI) -> None:
    """503 / 507 for storage failures on every route (see the module)."""

    async def handle(request: Request, exc: Exception) -> JSONResponse:
        answer = storage_answer(exc)
        if answer is None:
            raise exc
        code, detail = answer
        collector = getattr(request.app.state, "metrics_collector", None)
        if collector is not None:
            collector.http_errors[str(code)] = collector.http_errors.get(str(code), 0) + 1
        _log_once(str(code), detail, request.url.path)
        headers = {"Retry-After": "5"} if code == 503 else {}
        return JSONResponse({"detail": detail}, status_code=code, headers=headers)

    for exc_type in (OperationalError, InterfaceError, PoolTimeoutError, OSError):
        app.add_exception_handler(exc_type, handle)
