"""Database tables and API models, one SQLModel family per resource.

Table classes (`table=True`) are what the database holds; `*Create`, `*Update` and `*Public`
are what the API accepts and returns. Validation lives in the API models (SQLModel tables do
not validate on construction).
"""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime
from typing import Any, Literal

from pydantic import field_validator
from pydantic.json_schema import SkipJsonSchema
from sqlalchemy import JSON, Column, ForeignKey, Integer
from sqlmodel import Field, SQLModel

from rf_gateway.transport import normalize_address

Role = Literal["viewer", "operator", "admin"]
ROLES: tuple[Role, ...] = ("viewer", "operator", "admin")

MAX_LANDMARK_ID = 2**31 - 1
DECIMAL_ID = re.compile(r"0|[1-9][0-9]{0,9}")
"""A landmark ID as text (path, CSV): plain decimal digits, no sign, `_`, point or padding."""
MAX_ABS_XY_M = 10_000.0
"""Floor coordinates beyond this (10 km) are refused as absurd."""
MAX_Z_M = 100.0
"""LED heights above this are refused as absurd (ceilings, not towers)."""


RADIO_SCHEMA = {"json_schema_extra": {"pattern": "^[0-9A-Fa-f]{16}$"}}
"""The radio address as the schema states it (the server also takes `0x`, `:`, `-`, spaces)."""
RADIO_DOC = "64-bit radio address, 16 hex digits (null: none)"
X_DOC = "metres, map frame (REP-103/105: x, y on the floor, z up)"
XY_SCHEMA = {"json_schema_extra": {"minimum": -10_000.0, "maximum": 10_000.0}}
Z_SCHEMA = {"json_schema_extra": {"minimum": 0.0, "maximum": 100.0}}
"""The bounds `check_coordinate` enforces, as the schema states them."""


def utcnow() -> datetime:
    """Now, UTC (timezone-aware)."""
    return datetime.now(UTC)


def check_coordinate(name: str, value: float | None) -> float | None:
    """A finite coordinate within the site's bounds; ValueError names the field."""
    if value is None:
        return None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number of metres, got {value!r}")
    limit = MAX_Z_M if name == "z" else MAX_ABS_XY_M
    low = 0.0 if name == "z" else -limit
    if not low <= value <= limit:
        raise ValueError(f"{name} = {value} m is outside [{low}, {limit}] m")
    return value


def check_radio(value: str | None) -> str | None:
    """A 64-bit radio address (16 hex digits, normalised) or None."""
    if value is None:
        return None
    return normalize_address(value, source="radio")


# -- landmarks ---------------------------------------------------------------------------
class LandmarkBase(SQLModel):
    x: float = Field(description="LED position x, " + X_DOC, schema_extra=XY_SCHEMA)
    y: float = Field(description="LED position y, " + X_DOC, schema_extra=XY_SCHEMA)
    z: float = Field(description="LED height above the floor, " + X_DOC, schema_extra=Z_SCHEMA)
    radio: str | None = Field(default=None, description=RADIO_DOC, schema_extra=RADIO_SCHEMA)
    locked: bool = Field(default=False, description="surveyed: not moved by commissioning")
    note: str = Field(default="", max_length=1000, description="free text")


class Landmark(LandmarkBase, table=True):
    __tablename__ = "landmarks"
    id: int = Field(primary_key=True, sa_column_kwargs={"autoincrement": False})
    radio: str | None = Field(default=None, unique=True, index=True)
    created_at: datetime = Field(default_factory=utcnow)
    updated_at: datetime = Field(default_factory=utcnow)


def strict_number(name: str, v: object) -> object:
    """A JSON number (`true`, `"1.5"` are refused); ValueError names the field."""
    if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
        raise ValueError(f"{name}: expected a number of metres, got {v!r}")
    return v


def strict_bool(name: str, v: object) -> object:
    """A JSON boolean (`0`, `"yes"` are refused); ValueError names the field."""
    if v is not None and not isinstance(v, bool):
        raise ValueError(f"{name}: expected true or false, got {v!r}")
    return v


class LandmarkCreate(LandmarkBase):
    id: int = Field(ge=0, le=MAX_LANDMARK_ID, description="landmark ID (a JSON integer)")

    @field_validator("locked", mode="before")
    @classmethod
    def _strict_locked(cls, v: object) -> object:
        return strict_bool("locked", v)

    @field_validator("x", "y", "z", mode="before")
    @classmethod
    def _strict_xyz(cls, v: object, info: Any) -> object:
        return strict_number(info.field_name, v)

    @field_validator("id", mode="before")
    @classmethod
    def _strict_id(cls, v: object) -> object:
        if isinstance(v, float) and v.is_integer():  # JSON Schema's integer: 7.0 is one
            return int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            raise ValueError(f"expected an integer, got {v!r} ({type(v).__name__})")
        return v

    @field_validator("x", "y", "z")
    @classmethod
    def _coord(cls, v: float, info: Any) -> float:
        return check_coordinate(info.field_name, v)  # type: ignore[return-value]

    @field_validator("radio")
    @classmethod
    def _radio(cls, v: str | None) -> str | None:
        return check_radio(v)


class LandmarkUpdate(SQLModel):
    """The fields to change; those left out keep their value (`radio: null` clears it)."""

    x: float | SkipJsonSchema[None] = Field(
        default=None, description="LED position x, " + X_DOC, schema_extra=XY_SCHEMA
    )
    y: float | SkipJsonSchema[None] = Field(
        default=None, description="LED position y, " + X_DOC, schema_extra=XY_SCHEMA
    )
    z: float | SkipJsonSchema[None] = Field(
        default=None, description="LED height above the floor, " + X_DOC, schema_extra=Z_SCHEMA
    )
    radio: str | None = Field(default=None, description=RADIO_DOC, schema_extra=RADIO_SCHEMA)
    locked: bool | SkipJsonSchema[None] = None
    note: str | SkipJsonSchema[None] = Field(default=None, max_length=1000)

    @field_validator("x", "y", "z", "locked", "note", mode="before")
    @classmethod
    def _not_null(cls, v: object, info: Any) -> object:
        if v is None:
            raise ValueError(f"{info.field_name} cannot be null (leave it out to keep it)")
        if info.field_name == "locked":
            return strict_bool("locked", v)
        return strict_number(info.field_name, v) if info.field_name in "xyz" else v

    @field_validator("x", "y", "z")
    @classmethod
    def _coord(cls, v: float | None, info: Any) -> float | None:
        return check_coordinate(info.field_name, v)

    @field_validator("radio")
    @classmethod
    def _radio(cls, v: str | None) -> str | None:
        return check_radio(v)


class LandmarkPublic(LandmarkBase):
    id: int
    created_at: datetime
    updated_at: datetime


class MapDocument(SQLModel):
    """map.json: `{"landmarks": [{"id", "x", "y", "z", "radio"?, ...}]}`."""

    landmarks: list[LandmarkCreate]


# -- robots ------------------------------------------------------------------------------
class RobotBase(SQLModel):
    source: str = Field(default="sim", regex=r"^(sim|camera|remote)$")
    device: str | None = Field(default=None, description="camera index or video file (camera)")
    wheel_port: str | None = Field(
        default=None,
        max_length=300,
        description="serial port (device or pyserial URL) sending `$IRODO` wheel-speed lines",
    )
    wheel_baud: int = Field(default=115200, ge=50, le=4_000_000, description="its baud rate")
    wheel_base: float = Field(gt=0, le=10, description="metres between the wheels")
    max_speed: float = Field(default=1.0, gt=0, le=20, description="m/s")
    camera: dict[str, Any] = Field(
        default_factory=dict,
        sa_column=Column(JSON, nullable=False),
        description="cam0/sensor.yaml as JSON (intrinsics, distortion, T_BS mounting)",
    )


class Robot(RobotBase, table=True):
    __tablename__ = "robots"
    name: str = Field(primary_key=True, max_length=64)
    created_at: datetime = Field(default_factory=utcnow)
    updated_at: datetime = Field(default_factory=utcnow)


class RobotCreate(RobotBase):
    name: str = Field(min_length=1, max_length=64, regex=r"^[A-Za-z0-9_.-]+$")


class RobotPublic(RobotBase):
    name: str


# -- battery, events, audit ----------------------------------------------------------------
class BatteryRecord(SQLModel, table=True):
    __tablename__ = "battery_readings"
    id: int | None = Field(default=None, primary_key=True)
    landmark_id: int = Field(
        sa_column=Column(Integer, ForeignKey("landmarks.id", ondelete="CASCADE"), index=True)
    )
    t: datetime = Field(default_factory=utcnow, index=True)
    supply_mv: int


class EventRecord(SQLModel, table=True):
    __tablename__ = "events"
    id: int | None = Field(default=None, primary_key=True)
    t: datetime = Field(default_factory=utcnow, index=True)
    kind: str = Field(index=True)
    robot: str | None = None
    landmark_id: int | None = None
    message: str = ""
    data: dict[str, Any] = Field(default_factory=dict, sa_column=Column(JSON, nullable=False))


class AuditRecord(SQLModel, table=True):
    __tablename__ = "audit_log"
    id: int | None = Field(default=None, primary_key=True)
    t: datetime = Field(default_factory=utcnow, index=True)
    actor: str
    action: str
    landmark_id: int | None = Field(default=None, index=True)
    before: dict[str, Any] | None = Field(default=None, sa_column=Column(JSON, nullable=True))
    after: dict[str, Any] | None = Field(default=None, sa_column=Column(JSON, nullable=True))
    target_id: int | None = Field(
        default=None, description="for `undo` and `redo`: the audit record they revert/reapply"
    )
    undo_state: str = Field(
        default="",
        description="for edits: '' (in effect), 'undone' (may be redone) or 'dropped' "
        "(undone, then its author made a new edit: no longer redoable)",
    )


# -- API keys ------------------------------------------------------------------------------
class ApiKey(SQLModel, table=True):
    __tablename__ = "api_keys"
    id: int | None = Field(default=None, primary_key=True)
    name: str = ""
    role: str
    prefix: str = Field(description="first characters of the key, to recognise it")
    hash: str = Field(unique=True, index=True, description="sha256 of the key, hex")
    created_at: datetime = Field(default_factory=utcnow)
    revoked: bool = False
    last_used_at: datetime | None = None


class ApiKeyPublic(SQLModel):
    id: int
    name: str
    role: str
    prefix: str
    created_at: datetime
    revoked: bool
    last_used_at: datetime | None = Field(
        default=None, description="last request with this key (UTC, to the minute)"
    )
