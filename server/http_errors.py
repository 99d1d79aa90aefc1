"""HTTP error answers that name the problem where FastAPI's defaults do not.

`install_body_errors(app)`: a request body FastAPI could not parse is answered 400 with
what was wrong (`body: JSON nested too deeply`, `body: not UTF-8 text`) instead of "There was
an error parsing the body" (413 for a body that passed its limit while it was read); a 405
lists in `Allow` every method the path supports (Starlette
names only those of the first route of that path); every other HTTP error keeps FastAPI's
own answer. `refuse_unknown_query`: a dependency of every API route (422 for a query
parameter the route does not take).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from fastapi import FastAPI, Request
from fastapi.dependencies.models import Dependant
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException
from starlette.requests import HTTPConnection
from starlette.routing import Match
from starlette.types import Scope

from server.edge import BodyTooLargeError


def body_problem(exc: BaseException | None) -> str | None:
    """What was wrong with an unparsable body, from the exception FastAPI caught."""
    if isinstance(exc, RecursionError):
        return "body: JSON nested too deeply"
    if isinstance(exc, UnicodeDecodeError):
        return f"body: not UTF-8 text (byte {exc.start})"
    return None


METHODS = ("DELETE", "GET", "HEAD", "PATCH", "POST", "PUT")


def allowed_methods(app: FastAPI, scope: Scope) -> list[str]:
    """The HTTP methods some route of `app` fully matches for the request of `scope`."""
    allowed = []
    for method in METHODS:
        probe = {**scope, "method": method}
        if any(route.matches(probe)[0] == Match.FULL for route in app.router.routes):
            allowed.append(method)
    return allowed


def methods_of_other_routes(app: FastAPI, scope: Scope, prefix: str = "/api/v1") -> list[str]:
    """The methods of routes with a fixed path (no parameter) whose path is that of `scope`
    (with or without the API `prefix`): `PATCH /landmarks/audit` matched `PATCH
    /landmarks/{landmark_id}` and failed its validation, but the path is `GET
    /landmarks/audit`'s."""
    path = scope["path"]
    allowed: set[str] = set()
    for route in api_routes(app.router.routes):
        if "{" not in route.path and path in (route.path, prefix + route.path):
            allowed |= route.methods or set()
    return [m for m in METHODS if m in allowed]


def api_routes(routes: Iterable[Any]) -> Iterator[APIRoute]:
    """Every `APIRoute`, those of included routers too."""
    for route in routes:
        if isinstance(route, APIRoute):
            yield route
        router = getattr(route, "original_router", None)  # FastAPI's included router
        if router is not None:
            yield from api_routes(router.routes)


ALWAYS_ALLOWED = frozenset({"token"})
"""Query parameters every route takes (the API key, where headers cannot be set)."""


def query_names(dependant: Dependant) -> set[str]:
    """The query parameters a route (with its dependencies) takes."""
    names = {p.alias for p in dependant.query_params}
    for sub in dependant.dependencies:
        names |= query_names(sub)
    return names


def refuse_unknown_query(conn: HTTPConnection) -> None:
    """A dependency refusing query parameters the route does not take (422 naming the
    first), so that a misspelt `?allow_emtpy=true` is not silently ignored."""
    route = conn.scope.get("route")
    if not isinstance(route, APIRoute):
        return
    known = query_names(route.dependant)
    unknown = [k for k in conn.query_params if k not in known and k not in ALWAYS_ALLOWED]
    if unknown:
        takes = ", ".join(sorted(known | ALWAYS_ALLOWED))
        raise RequestValidationError(
            [
                {
                    "loc": ("query", unknown[0]),
                    "msg": f"unknown query parameter {unknown[0]!r} (this takes: {takes})",
                    "type": "extra_forbidden",
                }
            ]
        )


def install_body_errors(app: FastAPI) -> None:
    async def handle(request: Request, exc: Exception) -> Response:
        assert isinstance(exc, HTTPException)  # registered for HTTPException only
        if exc.status_code == 400 and isinstance(exc.__cause__, BodyTooLargeError):
            return JSONResponse(
                {"detail": str(exc.__cause__)}, status_code=413, headers={"Connection": "close"}
            )
        problem = body_problem(exc.__cause__) if exc.status_code == 400 else None
        if problem is not None:
            return JSONResponse({"detail": problem}, status_code=400)
        if exc.status_code == 405:
            allowed = allowed_methods(app, request.scope)
            if allowed:
                return JSONResponse(
                    {"detail": f"method {request.method} not allowed: use {', '.join(allowed)}"},
                    status_code=405,
                    headers={"Allow": ", ".join(allowed)},
                )
        return await http_exception_handler(request, exc)

    app.add_exception_handler(HTTPException, handle)
