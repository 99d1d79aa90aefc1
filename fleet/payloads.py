"""The JSON payloads of irloc's MQTT topics (pydantic models) and their conversions to and
from the localizer's events.

Every time on the wire is the site server's wall clock, Unix nanoseconds (`t_ns`, `wall_ns`):
the agent converts to and from its own clocks with its measured offset (`fleet.clock`).
Decoding bad input raises `PayloadError` naming the topic and the field.
"""

from __future__ import annotations

import math
from typing import Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from localizer.events import LedRequest, LedsChanged, Mode, NoPose, PoseEstimate
from localizer.pose_quality import ReasonCode
from localizer.types import FloatArray

M = TypeVar("M", bound=BaseModel)
MAX_T_NS = 2**63 - 1


class PayloadError(ValueError):
    """A message that is not what its topic carries."""


class _Msg(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)

    def encode(self) -> bytes:
        return self.model_dump_json(exclude_none=True).encode()


def decode(model: type[M], topic: str, payload: bytes | bytearray | str) -> M:
    """Parse one message of `topic`; PayloadError names the topic and the bad field."""
    try:
        return model.model_validate_json(payload)
    except ValidationError as exc:
        err = exc.errors()[0]
        where = ".".join(str(p) for p in err["loc"]) or "message"
        raise PayloadError(f"{topic}: {where}: {err['msg']}") from None


class MapLandmark(_Msg):
    id: int = Field(ge=0)
    x: float = Field(allow_inf_nan=False)
    y: float = Field(allow_inf_nan=False)
    z: float = Field(allow_inf_nan=False)


class MapMessage(_Msg):
    """`<site>/map`: the landmark map (surveyed positions, metres, world frame)."""

    map_id: str = Field(min_length=1, max_length=128)
    landmarks: list[MapLandmark]
    floor: str = Field("0", min_length=1, max_length=32, description="the floor it maps")
    version: int = Field(0, ge=0, description="that floor's map version (0: not versioned)")

    def records(self) -> list[dict[str, float]]:
        """The landmarks as `LandmarkMap.from_records` takes them."""
        return [lm.model_dump() for lm in self.landmarks]


class FloorMessage(_Msg):
    """`agents/<robot>/floor` (retained): the floor the site has the robot on.

    Attributes:
        n: this assignment's number (the site's wall clock, ns, when it was made): a new
            one means the robot changed floors (or was told its floor again); a retained
            copy seen again after a reconnect has the same.
        floor: the floor (its map: `<site>/maps/<floor>`).
        version: that floor's map version now.
        near: (x, y, theta) on that floor where the robot is (the lift's node), metres and
            radians; absent when unknown. Given, the agent forgets its pose and identifies
            again near it.
    """

    n: int = Field(ge=0, le=MAX_T_NS)
    floor: str = Field(min_length=1, max_length=32)
    version: int = Field(0, ge=0)
    near: tuple[float, float, float] | None = None

    @field_validator("near")
    @classmethod
    def _finite_near(
        cls, v: tuple[float, float, float] | None
    ) -> tuple[float, float, float] | None:
        if v is not None and not all(math.isfinite(a) for a in v):
            raise ValueError("near: x, y and theta must be finite numbers")
        return v


class LedStateMessage(_Msg):
    """`<site>/leds`: one LED state of the site (`localizer.events.LedsChanged`), in force from
    `t_ns`; `seq` counts the server's states (a gap means a missed one)."""

    seq: int = Field(ge=0)
    t_ns: int = Field(ge=0, le=MAX_T_NS)
    lit: list[int] = []
    all_lit: bool = False
    changing: list[int] = []

    @classmethod
    def from_event(cls, seq: int, event: LedsChanged, t_ns: int) -> LedStateMessage:
        """`event` stamped `t_ns` (the server's wall clock)."""
        return cls(
            seq=seq,
            t_ns=t_ns,
            lit=sorted(event.lit),
            all_lit=event.all_lit,
            changing=sorted(event.changing),
        )

    def event(self, t_ns: int) -> LedsChanged:
        """The localizer event, stamped `t_ns` (the receiver's clock)."""
        return LedsChanged(t_ns, frozenset(self.lit), self.all_lit, frozenset(self.changing))


class LedRequestMessage(_Msg):
    """`agents/<robot>/led_request`: a robot's `localizer.events.LedRequest`."""

    lit: list[int] = []
    all_lit: bool = False
    dark: list[int] = []

    @classmethod
    def from_request(cls, req: LedRequest) -> LedRequestMessage:
        return cls(lit=sorted(req.lit), all_lit=req.all_lit, dark=sorted(req.dark))

    def request(self) -> LedRequest:
        """The request; ValueError when `dark` comes without `all_lit`."""
        return LedRequest(frozenset(self.lit), self.all_lit, frozenset(self.dark))


_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
COV_DIGITS = 4
"""Significant digits kept of each covariance entry."""
MAX_SPOTS = 64
"""Spots of one frame sent at most."""


def _sig(v: float, digits: int = COV_DIGITS) -> float:
    return float(f"{v:.{digits}g}")


class PoseMessage(_Msg):
    """`agents/<robot>/pose`: one localizer result.

    Attributes:
        seq: counts the agent's pose messages.
        t_ns: the frame's time (site server's wall clock, ns).
        wall_ns: when the agent computed it (site server's wall clock, ns).
        mode: the localizer's mode.
        x, y, theta: metres, metres, radians (REP-103); absent while there is no pose.
        cov: the covariance of (x, y, theta), upper triangle row by row
            (xx, xy, xt, yy, yt, tt), SI units.
        lm: the landmarks used for this pose.
        floor, map_version: the floor and map version the agent localized on (absent from
            agents that do not say).
        floor_unknown: true when its view does not fit its floor's map (it changed floors
            untold, or rides a lift; `fleet.floor_fit`): the pose is withheld (no x, y,
            theta) until it is told its floor or fits its map again.
        ex: the lit landmarks the localizer expected in view (sent with `spots`).
        spots: the frame's spot centres (col, row) in pixels, for map upkeep: sent with a
            confident frame now and then (`AgentConfig.spots_period_s`), else absent.
        quality: 0-1 (docs/quality.md); deviation_m: the 95 % radius, metres.
        reason, reason_text: why this is no landmark fix (absent when it is one).
    """

    seq: int = Field(ge=0)
    t_ns: int = Field(ge=0, le=MAX_T_NS)
    wall_ns: int = Field(ge=0, le=MAX_T_NS)
    mode: Mode
    x: float | None = Field(default=None, allow_inf_nan=False)
    y: float | None = Field(default=None, allow_inf_nan=False)
    theta: float | None = Field(default=None, allow_inf_nan=False)
    cov: tuple[float, float, float, float, float, float] | None = None
    lm: list[int] = []
    floor: str | None = Field(default=None, min_length=1, max_length=32)
    map_version: int | None = Field(default=None, ge=0)
    floor_unknown: bool | None = None
    ex: list[int] | None = None
    spots: list[tuple[float, float]] | None = Field(default=None, max_length=MAX_SPOTS)
    quality: float | None = Field(default=None, ge=0.0, le=1.0)
    deviation_m: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)
    reason: ReasonCode | None = None
    reason_text: str | None = Field(default=None, max_length=300)

    @classmethod
    def from_no_pose(cls, seq: int, out: NoPose, t_ns: int, wall_ns: int) -> PoseMessage:
        return cls(
            seq=seq,
            t_ns=t_ns,
            wall_ns=wall_ns,
            mode=out.mode,
            quality=out.quality,
            reason=out.reason,
            reason_text=out.reason_text or None,
        )

    @field_validator("spots")
    @classmethod
    def _finite_spots(cls, v: list[tuple[float, float]] | None) -> list[tuple[float, float]] | None:
        if v is not None and not all(math.isfinite(a) and math.isfinite(b) for a, b in v):
            raise ValueError("spots: every pixel must be a finite number")
        return v

    @classmethod
    def from_estimate(
        cls,
        seq: int,
        est: PoseEstimate,
        t_ns: int,
        wall_ns: int,
        spots: FloatArray | None = None,
    ) -> PoseMessage:
        """The message of an estimate, with the frame's `spots` (N, 2) when given."""
        c = np.asarray(est.covariance, dtype=np.float64)
        return cls(
            seq=seq,
            t_ns=t_ns,
            wall_ns=wall_ns,
            mode=est.mode,
            x=round(float(est.x), 5),
            y=round(float(est.y), 5),
            theta=round(float(est.theta), 6),
            cov=tuple(_sig(float(c[i, j])) for i, j in _UPPER),  # type: ignore[arg-type]
            lm=list(est.landmark_ids),
            ex=list(est.expected_ids) if spots is not None else None,
            spots=None
            if spots is None
            else [(round(float(u), 2), round(float(v), 2)) for u, v in spots[:MAX_SPOTS]],
            quality=None if est.quality is None else round(est.quality, 3),
            deviation_m=None if est.deviation_m is None else _sig(est.deviation_m),
            reason=est.reason,
            reason_text=est.reason_text or None,
        )

    def covariance(self) -> FloatArray | None:
        """The full (3, 3) covariance, or None."""
        if self.cov is None:
            return None
        xx, xy, xt, yy, yt, tt = self.cov
        return np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]], dtype=np.float64)


AgentSource = Literal["sim", "sim-light", "camera"]


class AgentStatus(_Msg):
    """`agents/<robot>/status` (retained): what the server needs to show the robot.

    Attributes:
        source: "sim" (rendered frames), "sim-light" (spot-level simulation), "camera".
        camera: its camera as `cam0/sensor.yaml` (intrinsics, distortion, mounting `T_BS`).
        wheel_base, max_speed: metres, m/s.
        mode: the localizer's mode now.
        clock_offset_ns, clock_error_ns: server clock minus the agent's, and its bound (ns);
            absent before the first measurement.
        frames, poses, errors: counters of the agent's localizer.
        map_id: the map the agent localizes on.
        map_version: that map's version (`MapMessage.version`); the server tells an agent
            holding an old one (event `agent_map_outdated`, the map published again).
        floor: the floor whose map it localizes on (before it holds one: the floor it
            starts on, when it knows); a new agent is put on that floor.
    """

    source: AgentSource
    camera: dict[str, object]
    wheel_base: float = Field(gt=0, le=10)
    max_speed: float = Field(gt=0, le=20)
    mode: Mode
    clock_offset_ns: int | None = None
    clock_error_ns: int | None = None
    frames: int = 0
    poses: int = 0
    errors: int = 0
    map_id: str | None = None
    map_version: int | None = None
    floor: str | None = Field(default=None, min_length=1, max_length=32)


class ClockRequest(_Msg):
    """`<site>/clock/request`: agent `robot` sends at `t1` (its clock), id `n`."""

    robot: str
    n: int
    t1: int


class ClockReply(_Msg):
    """`agents/<robot>/clock/reply`: the request's `n`, `t1`, and the server's receive and
    send times `t2`, `t3` (its wall clock)."""

    n: int
    t1: int
    t2: int
    t3: int


class CommandMessage(_Msg):
    """`agents/<robot>/command`: an operator's request (relocalize, optionally near a pose
    (x, y, theta), metres and radians)."""

    command: Literal["relocalize"]
    near: tuple[float, float, float] | None = None


class ServerState(_Msg):
    """`<site>/server` (retained; last will OFFLINE)."""

    state: Literal["ONLINE", "OFFLINE"]
