"""Log output of `irloc serve`: human-readable lines (default) or one JSON object a line.

JSON lines carry `time` (UTC, ISO 8601, milliseconds), `level`, `logger`, `message`, the
fields given with `extra=` (e.g. `log.warning("...", extra={"robot": "r1"})` gives
`"robot": "r1"`; `robot`, `landmark`, `port` are the ones the server uses) and `exc` (the
traceback) when there is one. Everything, uvicorn's own logs included, goes to stderr.

No API key reaches a line (`RedactKeys`, on the handler, so in both formats and for every
logger, uvicorn's access lines included): `token=`, `key=` and `irloc_ticket=` query values,
`Bearer` credentials and anything shaped like an irloc key become `[redacted]`, in the
message, the `extra=` fields and tracebacks.
"""

from __future__ import annotations

import json
import logging
import re
import sys
from datetime import UTC, datetime
from typing import IO, Any, Literal

LogFormat = Literal["text", "json"]
TEXT_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
_STANDARD = set(vars(logging.LogRecord("", 0, "", 0, "", None, None))) | {
    "message",
    "asctime",
    "color_message",  # uvicorn's copy of the message with terminal colours
}
QUIET = {"alembic.runtime.plugins": logging.WARNING}
"""Loggers too chatty at info (alembic lists its plugins at every start)."""

REDACTED = "[redacted]"
_SECRETS = (
    (re.compile(r"(?i)\b(token|key|irloc_ticket)=[^&\s\"'#]+"), rf"\1={REDACTED}"),
    (re.compile(r"(?i)\bBearer\s+[^\s\"',;]+"), f"Bearer {REDACTED}"),
    (re.compile(r"\birloc_[A-Za-z0-9_-]{16,}"), f"irloc_{REDACTED}"),
    (re.compile(r"(?i)\b([a-z][a-z0-9+.-]*://[^:/@\s]+):[^@/\s]+@"), rf"\1:{REDACTED}@"),
)


def redact(text: str) -> str:
    """`text` with API keys (query values, bearer credentials, bare keys) replaced."""
    for pattern, replacement in _SECRETS:
        text = pattern.sub(replacement, text)
    return text


class RedactKeys(logging.Filter):
    """Rewrites each record in place so that no API key is formatted: the message (with its
    arguments merged in), string `extra=` fields, the traceback and the stack."""

    def filter(self, record: logging.LogRecord) -> bool:
        record.msg = redact(record.getMessage())
        record.args = None
        for key, value in list(vars(record).items()):
            if key not in _STANDARD and isinstance(value, str):
                setattr(record, key, redact(value))
        if record.exc_info:
            record.exc_text = logging.Formatter().formatException(record.exc_info)
            record.exc_info = None
        if record.exc_text:
            record.exc_text = redact(record.exc_text)
        if record.stack_info:
            record.stack_info = redact(record.stack_info)
        return True


class JsonFormatter(logging.Formatter):
    """One JSON object per record (no newlines inside: tracebacks are escaped)."""

    def format(self, record: logging.LogRecord) -> str:
        out: dict[str, Any] = {
            "time": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname,
            "logger": record.name,
            "message": record.getMessage(),
        }
        for key, value in vars(record).items():
            if key not in _STANDARD and not key.startswith("_") and key not in out:
                out[key] = value
        if record.exc_info:
            out["exc"] = self.formatException(record.exc_info)
        elif record.exc_text:
            out["exc"] = record.exc_text
        return json.dumps(out, default=str, ensure_ascii=False)


class QuietRefusals(logging.Filter):
    """Leaves 401 and 429 answers out of uvicorn's access log: a flood of bad keys would
    write a line each (`server.throttle` logs them as one line per burst)."""

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        return not (isinstance(args, tuple) and len(args) >= 5 and args[4] in (401, 429))


def configure_logging(
    level: str = "info", fmt: LogFormat = "text", stream: IO[str] | None = None
) -> logging.Handler:
    """Send every log record of at least `level` to `stream` (stderr) in format `fmt`;
    replaces the root logger's handlers and makes uvicorn's loggers use them."""
    if fmt not in ("text", "json"):
        raise ValueError(f"log format: expected 'text' or 'json', got {fmt!r}")
    handler = logging.StreamHandler(stream or sys.stderr)
    handler.setFormatter(JsonFormatter() if fmt == "json" else logging.Formatter(TEXT_FORMAT))
    handler.addFilter(RedactKeys())
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(level.upper())
    for name, quiet_level in QUIET.items():
        logging.getLogger(name).setLevel(quiet_level)
    access = logging.getLogger("uvicorn.access")
    if not any(isinstance(f, QuietRefusals) for f in access.filters):
        access.addFilter(QuietRefusals())
    for name in ("uvicorn", "uvicorn.error", "uvicorn.access"):
        lg = logging.getLogger(name)
        lg.handlers.clear()
        lg.setLevel(logging.NOTSET)  # the root's level decides (uvicorn may have set its own)
        lg.propagate = True
    return handler
