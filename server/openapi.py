"""The OpenAPI document as the server really behaves, for clients generated from it.

`install_openapi(app)` (called by the app factory):

- names every operation for what it does (`get_robot_pose`, `replace_map`): the route
  function's name, or the name in `OPERATION_IDS`;
- declares the error answers each operation can give, all `{"detail": "<what is wrong>"}`
  (`ErrorResponse`; a 422 from parameter or body validation adds `errors`, one item per
  problem: `ValidationErrorResponse`): 400 (an unparsable body), 401 / 403 / 429 (key
  missing or bad, role too low, too many bad keys) wherever a key is needed, 404 (no such
  landmark, robot or key) where the path names one, 409 (a clash with what exists) on
  writes, 422 (bad parameters or body), 503 / 504 (the radio or the site is not running, a
  landmark's radio did not answer) where the radio or the live site is involved;
- puts every schema under `components/schemas` (no dangling `$defs`), names the multipart
  body of the lens upload `LensCalibrationUpload`.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from pydantic import BaseModel, Field
from pydantic.json_schema import models_json_schema

from server.http_errors import api_routes
from store.models import LandmarkCreate, MapDocument

OPERATION_IDS: dict[str, str] = {
    "audit_log": "list_landmark_audit",
    "set_led": "set_landmark_led",
    "blink": "blink_landmark",
    "battery": "get_landmark_battery",
    "import_map": "replace_map",
    "get_pose": "get_robot_pose",
    "relocalize": "relocalize_robot",
    "wheel_speeds": "send_wheel_speeds",
    "get_config": "get_robot_config",
    "put_config": "replace_robot_config",
    "start_recording": "start_robot_recording",
    "stop_recording": "stop_robot_recording",
    "calibrate_lens_upload": "calibrate_robot_lens",
    "radio_state": "get_radio_state",
    "discover": "discover_radios",
    "event_stream": "stream_events",
    "_metrics": "get_metrics",
    "_healthz": "get_health",
    "list_doubts": "list_landmark_doubts",
    "wizard_status": "get_wizard_status",
    "wizard_start": "start_wizard",
    "wizard_confirm": "confirm_wizard_measurement",
    "wizard_skip": "skip_wizard_landmark",
    "wizard_switch_anyway": "switch_wizard_leds_anyway",
    "wizard_cancel": "cancel_wizard",
}
"""Route function name -> operation id, where the function's own name does not say it."""
RENAMED_SCHEMAS = {
    "Body_calibrate_robot_lens": "LensCalibrationUpload",
}
RADIO_OR_SITE = ("/led", "/blink", "/battery", "/radio", "/robots/{name}/")
"""Path parts of operations that need the radio or the live site (503; radio also 504)."""
RADIO = ("/led", "/blink", "/battery", "/radio/discover")


class ErrorResponse(BaseModel):
    """Every error answer."""

    detail: str = Field(description="what was wrong, in a sentence naming the value")


class ValidationIssue(BaseModel):
    loc: list[str | int] = Field(description="where: `body`, `query`, `path`, then the field")
    msg: str = Field(description="what is wrong there")
    type: str = Field(description="pydantic's error type, e.g. `int_parsing`")


class ValidationErrorResponse(BaseModel):
    """A 422: bad parameters or body."""

    detail: str = Field(description="the problems, `loc: msg` joined by `; `")
    errors: list[ValidationIssue] = Field(
        default=[], description="each problem (empty when the service refused the value)"
    )


ERRORS: dict[int, str] = {
    400: "the body could not be parsed (not UTF-8, JSON nested too deeply)",
    401: "a valid API key is required (`Authorization: Bearer <key>` or `?token=`)",
    403: "the key's role is too low for this",
    404: "no such landmark, robot or key",
    409: "the change clashes with what exists (duplicate ID or radio, an empty map)",
    422: "bad parameters or body; `detail` names the field and the problem",
    429: "too many requests with bad keys from this address: see `Retry-After`",
    503: "the radio or the live site is not running",
    504: "a landmark's radio did not answer",
}


def _error_codes(method: str, path: str, op: dict[str, Any]) -> list[int]:
    codes = [422] if op.get("parameters") or op.get("requestBody") else []
    if op.get("security"):  # a key; any query or body may name a landmark or robot
        codes += [401, 403, 404, 429]
    if "{" in path:
        codes.append(404)
    if method in ("post", "put", "patch", "delete"):
        codes += [400, 409]
    if any(part in path for part in RADIO_OR_SITE):
        codes.append(503)
    if any(part in path for part in RADIO) or path.endswith("/relocalize"):
        codes.append(504)
    return sorted(set(codes))


def _ref(name: str) -> dict[str, str]:
    return {"$ref": f"#/components/schemas/{name}"}


BOUNDS = {"gt": "exclusiveMinimum", "ge": "minimum", "lt": "exclusiveMaximum", "le": "maximum"}
"""pydantic's names of bounds, which FastAPI leaves in a form field's schema when its type is
a union: JSON Schema's names."""


def _rename(node: Any, renamed: dict[str, str]) -> Any:
    if isinstance(node, dict):
        if node.get("type") in ("number", "integer"):
            node = {BOUNDS.get(k, k): v for k, v in node.items()}
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.rsplit("/", 1)[-1] in renamed:
            node = {**node, "$ref": "#/components/schemas/" + renamed[ref.rsplit("/", 1)[-1]]}
        return {k: _rename(v, renamed) for k, v in node.items()}
    if isinstance(node, list):
        return [_rename(v, renamed) for v in node]
    return node


def refine(schema: dict[str, Any]) -> dict[str, Any]:
    """The document FastAPI made, refined as the module says (pure: dict in, dict out)."""
    models: list[type[BaseModel]] = [
        ErrorResponse,
        ValidationErrorResponse,
        MapDocument,
        LandmarkCreate,
    ]
    _, extra = models_json_schema(
        [(m, "validation") for m in models], ref_template="#/components/schemas/{model}"
    )
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    components.update(extra.get("$defs", {}))
    for old in ("HTTPValidationError", "ValidationError"):
        components.pop(old, None)
    for old, new in RENAMED_SCHEMAS.items():
        if old in components:
            components[new] = {**components.pop(old), "title": new}
    files = components.get("LensCalibrationUpload", {}).get("properties", {}).get("files")
    if files is not None:
        files["minItems"] = 1  # (an empty list of parts is no `files` field at all)
    for path, ops in schema.get("paths", {}).items():
        for method, op in ops.items():
            responses = op.setdefault("responses", {})
            for code in _error_codes(method, path, op):
                model = "ValidationErrorResponse" if code == 422 else "ErrorResponse"
                responses[str(code)] = {
                    "description": ERRORS[code],
                    "content": {"application/json": {"schema": _ref(model)}},
                }
    return dict(_rename(schema, RENAMED_SCHEMAS))


def install_openapi(app: FastAPI) -> None:
    """Name the operations and serve the refined document at `/openapi.json`."""
    for route in api_routes(app.routes):
        if route.operation_id is None:
            route.operation_id = OPERATION_IDS.get(route.name, route.name)
    plain = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = refine(plain())
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
