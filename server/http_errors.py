"""HTTP error answers that name the problem where FastAPI's defaults do not.

`install_body_errors(app)`: a request body FastAPI could not parse is answered 400 with
what was wrong (`body: JSON nested too deeply`, `body: not UTF-8 text`) instead of "There was
an error parsing the body"; every other HTTP error keeps FastAPI's own answer.
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException


def body_problem(exc: BaseException | None) -> str | None:
    """What was wrong with an unparsable body, from the exception FastAPI caught."""
    if isinstance(exc, RecursionError):
        return "body: JSON nested too deeply"
    if isinstance(exc, UnicodeDecodeError):
        return f"body: not UTF-8 text (byte {exc.start})"
    return None


def install_body_errors(app: FastAPI) -> None:
    async def handle(request: Request, exc: Exception) -> Response:
        assert isinstance(exc, HTTPException)  # registered for HTTPException only
        problem = body_problem(exc.__cause__) if exc.status_code == 400 else None
        if problem is not None:
            return JSONResponse({"detail": problem}, status_code=400)
        return await http_exception_handler(request, exc)

    app.add_exception_handler(HTTPException, handle)
