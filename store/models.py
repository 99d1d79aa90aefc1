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
from sqlalchemy import JSON, BigInteger, Column, ForeignKey, Integer, String, UniqueConstraint
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


DEFAULT_FLOOR = "0"
"""The floor of a landmark that names none (a single-floor site's map is floor "0")."""
FLOOR_ID = r"^[A-Za-z0-9_.-]{1,32}$"
"""A floor ID: 1-32 letters, digits, `_`, `.` or `-` (it appears in paths and MQTT topics)."""


FLOOR_SCHEMA = {"json_schema_extra": {"pattern": FLOOR_ID}}


def check_floor_id(value: str) -> str:
    """A floor ID (`FLOOR_ID`); ValueError names the bad value."""
    if not re.fullmatch(FLOOR_ID, value):
        raise ValueError(f"floor ID {value!r}: expected 1-32 letters, digits, '_', '.' or '-'")
    return value


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
    floor: str = Field(
        default=DEFAULT_FLOOR, max_length=32, description="the floor it hangs on (floor ID)"
    )
    sigma_m: float | None = Field(
        default=None,
        ge=0,
        le=10,
        description="1-sigma uncertainty of the position, metres: the largest semi-axis of "
        "its 1-sigma ellipsoid (null: not known, e.g. taped)",
    )
    covariance: list[list[float]] | None = Field(
        default=None,
        sa_column=Column(JSON, nullable=True),
        description="covariance of (x, y, z), 3 x 3, square metres (null: not known)",
    )
    evidence: dict[str, Any] | None = Field(
        default=None,
        sa_column=Column(JSON, nullable=True),
        description="where the position and its uncertainty come from: source (survey, map "
        "upkeep, ...), views, rms_px, ...",
    )

    @field_validator("covariance")
    @classmethod
    def _covariance(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        return check_covariance(v)


def check_covariance(v: list[list[float]] | None) -> list[list[float]] | None:
    """A 3 x 3 symmetric covariance of finite numbers with a non-negative diagonal."""
    if v is None:
        return v
    if len(v) != 3 or any(len(row) != 3 for row in v):
        raise ValueError(f"covariance: expected 3 x 3, got {v!r}")
    flat = [float(a) for row in v for a in row]
    if not all(math.isfinite(a) for a in flat) or min(v[i][i] for i in range(3)) < 0:
        raise ValueError(f"covariance: finite with a non-negative diagonal, got {v!r}")
    if any(abs(v[i][j] - v[j][i]) > 1e-9 * (1 + abs(v[i][j])) for i in range(3) for j in range(3)):
        raise ValueError(f"covariance: not symmetric: {v!r}")
    return v


class Landmark(LandmarkBase, table=True):
    __tablename__ = "landmarks"
    id: int = Field(primary_key=True, sa_column_kwargs={"autoincrement": False})
    floor: str = Field(default=DEFAULT_FLOOR, foreign_key="floors.id", index=True)
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
    covariance: SkipJsonSchema[list[list[float]] | None] = None  # as in LandmarkUpdate

    @field_validator("locked", mode="before")
    @classmethod
    def _strict_locked(cls, v: object) -> object:
        return strict_bool("locked", v)

    @field_validator("x", "y", "z", "sigma_m", mode="before")
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
    floor: str | SkipJsonSchema[None] = Field(
        default=None, max_length=32, description="move it to this floor (floor ID)"
    )
    sigma_m: float | None = Field(default=None, ge=0, le=10, description="metres; null: unknown")
    # written by the survey and map upkeep, not part of the API's input schema (a 3 x 3
    # covariance's constraints are beyond JSON Schema): sent by a client it is still checked
    covariance: SkipJsonSchema[list[list[float]] | None] = None
    evidence: dict[str, Any] | None = Field(default=None, description="source, views, ...")

    @field_validator("covariance")
    @classmethod
    def _covariance(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        return check_covariance(v)

    @field_validator("sigma_m", mode="before")
    @classmethod
    def _strict_sigma(cls, v: object) -> object:
        return strict_number("sigma_m", v)

    @field_validator("x", "y", "z", "locked", "note", "floor", mode="before")
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


# -- floors -------------------------------------------------------------------------------
class FloorBase(SQLModel):
    name: str = Field(min_length=1, max_length=100, description="what people call it")
    level: int = Field(
        ge=-50, le=300, description="storey number: 0 ground floor, 1 the one above, -1 below"
    )
    height: float = Field(
        default=0.0,
        ge=-1000.0,
        le=1000.0,
        description="elevation of the floor above the site's datum (level 0's floor), metres",
    )


class Floor(FloorBase, table=True):
    __tablename__ = "floors"
    id: str = Field(primary_key=True, max_length=32)
    created_at: datetime = Field(default_factory=utcnow)


class FloorCreate(FloorBase):
    id: str = Field(description="floor ID: 1-32 letters, digits, _ . -", schema_extra=FLOOR_SCHEMA)

    @field_validator("id")
    @classmethod
    def _floor_id(cls, v: str) -> str:
        return check_floor_id(v)


class FloorUpdate(SQLModel):
    """The fields to change; those left out keep their value."""

    name: str | SkipJsonSchema[None] = Field(default=None, min_length=1, max_length=100)
    level: int | SkipJsonSchema[None] = Field(default=None, ge=-50, le=300)
    height: float | SkipJsonSchema[None] = Field(default=None, ge=-1000.0, le=1000.0)

    @field_validator("name", "level", "height", mode="before")
    @classmethod
    def _not_null(cls, v: object, info: Any) -> object:
        if v is None:
            raise ValueError(f"{info.field_name} cannot be null (leave it out to keep it)")
        if isinstance(v, bool) and info.field_name != "name":
            raise ValueError(f"{info.field_name} must be a number, not {v!r}")
        return v


class FloorPublic(FloorBase):
    id: str
    version: int = Field(description="its map's version (bumped by every change of its map)")
    hash: str = Field(description="sha256 of its map's content, hex")
    landmarks: int = Field(description="landmarks on it")


class MapVersion(SQLModel, table=True):
    """One version of a floor's map: its content as it was, and who made it."""

    __tablename__ = "map_versions"
    __table_args__ = (UniqueConstraint("floor", "version"),)
    id: int | None = Field(default=None, primary_key=True)
    floor: str = Field(
        sa_column=Column(String, ForeignKey("floors.id", ondelete="CASCADE"), index=True)
    )
    version: int
    hash: str
    t: datetime = Field(default_factory=utcnow)
    actor: str = ""
    action: str = ""
    audit_id: int | None = None
    landmarks: list[dict[str, Any]] = Field(
        default_factory=list, sa_column=Column(JSON, nullable=False)
    )


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


# -- zones and pose history ----------------------------------------------------------------
class ZoneRecord(SQLModel, table=True):
    """A zone: a polygon on the floor (world x, y metres), on a floor of the site."""

    __tablename__ = "zones"
    id: int | None = Field(default=None, primary_key=True)
    name: str = Field(sa_column=Column(String, nullable=False, unique=True))
    floor: str = ""
    polygon: list[list[float]] = Field(sa_column=Column(JSON, nullable=False))
    dwell_s: float | None = None
    created_at: datetime = Field(default_factory=utcnow)


class PoseRecord(SQLModel, table=True):
    """One kept pose of a robot (the history keeps about one a second per robot)."""

    __tablename__ = "pose_history"
    id: int | None = Field(default=None, primary_key=True)
    robot: str
    t: datetime = Field(description="wall clock, UTC")
    t_ns: int = Field(sa_column=Column(BigInteger, nullable=False), description="site clock")
    x: float
    y: float
    theta: float
    sigma_m: float | None = None
    mode: str
    floor: str = Field(default="0", description="the floor whose map frame x, y are in")
