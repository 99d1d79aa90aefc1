"""The app factory: `create_app(settings, viewer) -> FastAPI`. Nothing is built at import time.

The lifespan builds `SiteServices` (database, migrations, first admin key), starts the live
site (radio, robots, clock), commissioning and the viewer it was handed (a
`server.seams.ViewerApp`; `irloc serve` builds `web.viewer.Viewer`: the server never imports
the viewer), and stops them in reverse order on shutdown.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import APIRouter, Depends, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from fastapi_offline import FastAPIOffline
from pydantic import ValidationError

from live.mqtt_bridge import start_mqtt_bridge
from live.services import SiteServices
from live.settings import Settings
from rf_gateway.errors import (
    LandmarkUnreachableError,
    RfGatewayError,
    TransportUnavailable,
    UnknownLandmarkError,
)
from server.auth import Viewer, authenticate
from server.edge import EdgeCounters, EdgeGuard
from server.fanout import PoseFanout
from server.health import Health, check_health
from server.http_errors import (
    install_body_errors,
    methods_of_other_routes,
    refuse_unknown_query,
)
from server.landing import landing_router
from server.metrics import make_registry, render
from server.openapi import install_openapi
from server.routes import (
    admin,
    alerts,
    calibration,
    commissioning,
    floorplan,
    floors,
    history,
    landmarks,
    leds,
    map,
    map_proposals,
    recordings,
    remote,
    robots,
    streams,
    survey,
    zones,
)
from server.seams import ViewerApp
from server.storage_errors import install_storage_errors
from store.errors import ConflictError, NotFoundError, UnavailableError

log = logging.getLogger(__name__)
API_PREFIX = "/api/v1"


def _error_status(exc: Exception) -> tuple[int, str]:
    if isinstance(exc, LandmarkUnreachableError):
        return 504, str(exc)
    if isinstance(exc, UnknownLandmarkError):
        return 404, str(exc)
    if isinstance(exc, NotFoundError):
        return 404, str(exc)
    if isinstance(exc, ConflictError):
        return 409, str(exc)
    if isinstance(exc, TransportUnavailable | UnavailableError):
        return 503, str(exc)
    if isinstance(exc, RfGatewayError):
        return 503, str(exc)
    if isinstance(exc, ValidationError):
        err = exc.errors()[0]
        return 422, f"{'.'.join(str(p) for p in err['loc'])}: {err['msg']}"
    return 422, str(exc)


def _install_error_handlers(app: FastAPI) -> None:
    async def handle(request: Request, exc: Exception) -> JSONResponse:
        code, message = _error_status(exc)
        collector = getattr(request.app.state, "metrics_collector", None)
        if collector is not None:
            key = str(code)
            collector.http_errors[key] = collector.http_errors.get(key, 0) + 1
        return JSONResponse({"detail": message}, status_code=code)

    for exc_type in (
        NotFoundError,
        ConflictError,
        UnavailableError,
        RfGatewayError,
        UnknownLandmarkError,
        ValidationError,
        ValueError,
    ):
        app.add_exception_handler(exc_type, handle)

    async def bad_request(request: Request, exc: Exception) -> JSONResponse:
        errors = exc.errors() if isinstance(exc, RequestValidationError) else []
        if any(e["loc"][:1] == ("path",) for e in errors):
            others = methods_of_other_routes(request.app, request.scope)
            if others and request.method not in others:  # the path is another route's
                return JSONResponse(
                    {"detail": f"method {request.method} not allowed: use {', '.join(others)}"},
                    status_code=405,
                    headers={"Allow": ", ".join(others)},
                )
        parts = [f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in errors[:5]]
        listed = [{"loc": list(e["loc"]), "msg": e["msg"], "type": e["type"]} for e in errors]
        return JSONResponse({"detail": "; ".join(parts), "errors": listed}, status_code=422)

    app.add_exception_handler(RequestValidationError, bad_request)
    install_storage_errors(app)


def create_app(settings: Settings | None = None, viewer: ViewerApp | None = None) -> FastAPI:
    """The irloc API for `settings` (defaults: environment / settings file), serving
    `viewer` under `/viewer/` when one is given."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = SiteServices(settings)
        app.state.services = services
        registry, collector = make_registry(services)
        app.state.metrics_registry = registry
        app.state.metrics_collector = collector
        collector.app_state = app.state
        await services.start()
        fanout = PoseFanout(services.poses, flush_s=settings.ws_flush_s)
        fanout.start()
        app.state.pose_fanout = fanout
        collector.fanout = fanout
        if viewer is not None:
            await asyncio.to_thread(viewer.start, services)
        app.state.viewer = viewer
        app.state.mqtt_bridge = await start_mqtt_bridge(services)
        try:
            yield
        finally:
            if app.state.mqtt_bridge is not None:
                await app.state.mqtt_bridge.stop()
            if viewer is not None:
                try:
                    # off the loop: the viewer may wait on coroutines it submits to it
                    await asyncio.to_thread(viewer.stop)
                except Exception:
                    log.exception("viewer did not stop cleanly")
            await fanout.stop()
            await services.stop()

    app = FastAPIOffline(  # Swagger UI and ReDoc from the package: plant networks are offline
        title="irloc",
        version="0.1.0",
        summary="Indoor localization with IR ceiling landmarks: map, robots, radio",
        lifespan=lifespan,
    )
    _install_error_handlers(app)
    install_body_errors(app)
    app.state.edge_counters = EdgeCounters()  # the guard is built lazily: /metrics reads these
    app.add_middleware(
        EdgeGuard, default_body_bytes=settings.max_body_bytes, counters=app.state.edge_counters
    )
    api = APIRouter(prefix=API_PREFIX, dependencies=[Depends(refuse_unknown_query)])
    for module in (
        landmarks,
        map,
        history,
        floorplan,
        robots,
        calibration,
        remote,
        admin,
        streams,
        commissioning,
        survey,
        leds,
        map_proposals,
        recordings,
        zones,
        floors,
        alerts,
    ):
        api.include_router(module.router)
    api.add_api_route(
        "/metrics",
        _metrics,
        methods=["GET"],
        tags=["operations"],
        response_class=Response,
        summary="Prometheus metrics",
    )
    app.include_router(api)
    app.add_api_route(
        "/healthz",
        _healthz,
        methods=["GET"],
        tags=["operations"],
        response_model=Health,
        responses={503: {"model": Health, "description": "degraded: `problems` names why"}},
    )
    app.add_api_route(
        API_PREFIX + "/healthz",
        _healthz,
        methods=["GET"],
        tags=["operations"],
        response_model=Health,
        include_in_schema=False,
    )
    if viewer is not None:
        app.include_router(viewer.router(authenticate))
    app.include_router(landing_router())
    install_openapi(app)
    return app


async def _healthz(request: Request) -> JSONResponse:
    """Health (no key needed): 200 when all is well, 503 naming the problems."""
    health = await check_health(request.app.state.services)
    code = 200 if not health.problems else 503
    return JSONResponse(health.model_dump(), status_code=code)


async def _metrics(request: Request, _: Viewer) -> Response:
    return Response(
        render(request.app.state.metrics_registry), media_type="text/plain; version=0.0.4"
    )
