"""`/robots`: list, pose, relocalize, configuration, wheel speeds, recordings."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Response, status
from pydantic import BaseModel, Field

from live.agent_runner import AgentRunner, agent_fields
from live.black_box import BlackBoxRecording
from live.floor_watch import FloorProposal, FloorWatch
from live.poses import PosePublic, pose_json
from live.vda5050 import init_positions
from localizer.camera import camera_from_sensor
from localizer.events import Mode, OdometryMeasured
from server.auth import Admin, Operator, Viewer
from server.deps import RobotName, ServicesDep
from server.robot_devices import check_devices
from store.errors import NotFoundError, UnavailableError
from store.models import RobotCreate, RobotPublic

router = APIRouter(prefix="/robots", tags=["robots"])


class RobotStatus(BaseModel):
    name: str
    source: str
    mode: Mode
    frames: int
    poses: int
    errors: int
    last_fix_t_ns: int | None
    recording: bool
    connected: bool | None = None
    clock_offset_s: float | None = None
    clock_error_s: float | None = None
    clock_ok: bool | None = None
    floor: str = Field("0", description="the floor whose map its localizer holds")
    map_version: int = Field(0, description="the version of that floor's map it holds")


class WheelSpeeds(BaseModel):
    """Wheel speeds measured now (or at `t_ns` on the site clock), m/s."""

    v_left: float = Field(ge=-20, le=20)
    v_right: float = Field(ge=-20, le=20)
    t_ns: int | None = Field(default=None, ge=0, le=2**62)


class RecordingStatus(BaseModel):
    robot: str
    recording: bool
    path: str | None = Field(default=None, description="the folder on the server")
    name: str | None = Field(
        default=None, description="the recording's name in GET /recordings/{name}[/download]"
    )


class BlackBoxPublic(BaseModel):
    """A saved black box: an ordinary recording (`irloc replay PATH`) of the seconds around
    a failure (docs/quality.md)."""

    robot: str
    trigger: Literal["lost", "kidnap", "quality", "operator"]
    reason: str | None = Field(description="the pose's reason code when it was triggered")
    t_ns: int = Field(description="site time of the trigger (and its aftermath), ns")
    saved_at: str
    bytes: int
    path: str

    @classmethod
    def of(cls, b: BlackBoxRecording) -> BlackBoxPublic:
        return cls(
            robot=b.robot,
            trigger=b.trigger,
            reason=b.reason,
            t_ns=b.t_ns,
            saved_at=b.saved_at,
            bytes=b.bytes,
            path=str(b.path),
        )


def _status(services: ServicesDep, name: str) -> RobotStatus:
    r = services.robots.get(name)
    agent = agent_fields(r) if isinstance(r, AgentRunner) else {}
    return RobotStatus(
        **agent,
        name=r.name,
        source=r.source,
        mode=r.mode,
        frames=r.frames,
        poses=r.poses,
        errors=r.errors,
        last_fix_t_ns=r.last_fix_t_ns,
        recording=r.recorder is not None,
        floor=r.floor,
        map_version=r.map_version,
    )


@router.get("")
async def list_robots(services: ServicesDep, _: Viewer) -> list[RobotStatus]:
    return [_status(services, n) for n in services.robots.names()]


@router.get("/{name}")
async def get_robot(name: RobotName, services: ServicesDep, _: Viewer) -> RobotStatus:
    return _status(services, name)


@router.get("/{name}/pose", response_model=PosePublic)
async def get_pose(name: RobotName, services: ServicesDep, _: Viewer) -> Response:
    """The latest pose: x, y, theta, covariance, mode, landmarks used, timestamp, age."""
    runner = services.robots.get(name)
    text = pose_json(
        name,
        runner.mode,
        runner.latest,
        floor=runner.floor,
        map_version=runner.map_version,
        now=runner.reasons.last,
    )
    return Response(text, media_type="application/json")


class PoseHint(BaseModel):
    """Where the robot is thought to be (world frame, REP-103 heading)."""

    x: float = Field(allow_inf_nan=False, ge=-1e4, le=1e4, description="metres")
    y: float = Field(allow_inf_nan=False, ge=-1e4, le=1e4, description="metres")
    theta: float = Field(0.0, allow_inf_nan=False, ge=-7.0, le=7.0, description="radians")


class FloorChange(BaseModel):
    """The robot is now on `floor` (it left the lift there), near a pose of that floor's
    map when given (the lift's node)."""

    floor: str = Field(min_length=1, max_length=32, description="floor ID")
    near: PoseHint | None = Field(None, description="where on that floor (the lift's node)")


# the routes that feed a localizer are plain `def` (threadpool): the robot's lock may be held
# by a frame being localized, which must not block the event loop (and the pose streams)
@router.post("/{name}/relocalize", status_code=status.HTTP_202_ACCEPTED)
def relocalize(
    name: RobotName, services: ServicesDep, _: Operator, near: PoseHint | None = None
) -> RobotStatus:
    """Forget the robot's pose and identify its landmarks again; with a body
    `{"x": .., "y": .., "theta": ..}` it starts from there (nearby landmarks first, and the
    pose may be confirmed from the map at once)."""
    services.robots.relocalize(name, None if near is None else (near.x, near.y, near.theta))
    return _status(services, name)


@router.post("/{name}/floor", status_code=status.HTTP_202_ACCEPTED)
def change_floor(
    name: RobotName, body: FloorChange, services: ServicesDep, who: Operator
) -> RobotStatus:
    """The robot is now on another floor (it left the lift there): its localizer takes that
    floor's map and identifies again, near `x, y, theta` when given. 404 naming an unknown
    robot or floor (nothing changes); an event `robot_floor_changed`."""
    near = None if body.near is None else (body.near.x, body.near.y, body.near.theta)
    services.site_floors.move(name, body.floor, near, by=who.actor)
    return _status(services, name)


class VdaActionParameter(BaseModel):
    key: str
    value: float | str | bool | None = None


class VdaAction(BaseModel):
    actionType: str = Field(description="`initPosition` (the only one carried out here)")
    actionId: str
    blockingType: str = "NONE"
    actionParameters: list[VdaActionParameter] = []


class VdaInstantActions(BaseModel):
    """A VDA 5050 `instantActions` message (its header fields are optional here)."""

    headerId: int | None = None
    timestamp: str | None = None
    version: str | None = None
    manufacturer: str | None = None
    serialNumber: str | None = None
    actions: list[VdaAction] = Field(min_length=1)


class InstantActionsResult(BaseModel):
    done: list[str] = Field(description="the actionIds carried out, in order")
    floor: str = Field(description="the robot's floor now")


@router.post("/{name}/instant-actions", status_code=status.HTTP_202_ACCEPTED)
def instant_actions(
    name: RobotName, body: VdaInstantActions, services: ServicesDep, who: Operator
) -> InstantActionsResult:
    """VDA 5050 `instantActions` for this robot: `initPosition` (`x`, `y`, `theta`,
    `mapId` = a floor ID) sets its floor and pose, e.g. as it leaves the lift. 422 naming a
    bad parameter or an action type not carried out, 404 naming an unknown floor; nothing
    is done then."""
    actions = [
        (a.actionType, a.actionId, {p.key: p.value for p in a.actionParameters})
        for a in body.actions
    ]
    inits = init_positions(actions)
    for init in inits:
        services.floors.check(init.map_id, what=f"action {init.action_id!r}: robot {name!r}")
    services.robots.get(name)
    for init in inits:
        services.site_floors.move(
            name, init.map_id, (init.x, init.y, init.theta), by=f"{who.actor} (initPosition)"
        )
    return InstantActionsResult(
        done=[i.action_id for i in inits], floor=services.robots.get(name).floor
    )


class FloorProposalPublic(BaseModel):
    """The floor a robot's view fits (it has no fix on its own floor's map), not yet taken."""

    robot: str
    floor: str = Field(description="the floor proposed")
    current_floor: str = Field(description="the floor the robot is on now")
    x: float = Field(description="its pose on the proposed floor's map: metres")
    y: float = Field(description="metres")
    theta: float = Field(description="radians")
    t_ns: int = Field(description="the time of that pose (site clock)")
    fixes: int = Field(description="landmark fixes in a row on the proposed floor")


def _watch(services: ServicesDep) -> FloorWatch:
    live = services.runner
    if live is None or live.floor_watch is None:
        raise UnavailableError("floor proposals need the live site and its radio")
    return live.floor_watch


def _proposal(services: ServicesDep, p: FloorProposal) -> FloorProposalPublic:
    return FloorProposalPublic(
        robot=p.robot,
        floor=p.floor,
        current_floor=services.robots.get(p.robot).floor,
        x=p.x,
        y=p.y,
        theta=p.theta,
        t_ns=p.t_ns,
        fixes=p.fixes,
    )


@router.get("/{name}/floor-proposal")
def get_floor_proposal(name: RobotName, services: ServicesDep, _: Viewer) -> FloorProposalPublic:
    """The floor the robot's view fits while it has no fix on its own (404 when none is
    proposed): nothing changes until it is accepted."""
    services.robots.get(name)
    found = _watch(services).proposal(name)
    if found is None:
        raise NotFoundError(f"robot {name!r} has no floor proposal")
    return _proposal(services, found)


@router.post("/{name}/floor-proposal/accept", status_code=status.HTTP_202_ACCEPTED)
def accept_floor_proposal(
    name: RobotName, services: ServicesDep, who: Operator
) -> FloorProposalPublic:
    """Move the robot to the proposed floor, near its latest pose there (404 without a
    proposal); an event `robot_floor_changed`."""
    services.robots.get(name)
    return _proposal(services, _watch(services).accept(name, by=f"{who.actor} (proposal)"))


@router.post("/{name}/floor-proposal/reject")
def reject_floor_proposal(
    name: RobotName, services: ServicesDep, _: Operator
) -> FloorProposalPublic:
    """Drop the proposal (404 without one); the robot is tried again later."""
    services.robots.get(name)
    return _proposal(services, _watch(services).reject(name))


@router.post("/{name}/odometry", status_code=status.HTTP_202_ACCEPTED)
def wheel_speeds(
    name: RobotName, body: WheelSpeeds, services: ServicesDep, _: Operator
) -> RobotStatus:
    """Wheel speeds for a robot whose camera is on the server (source `camera`)."""
    t_ns = body.t_ns if body.t_ns is not None else services.clock_ns()
    services.robots.get(name).handle(OdometryMeasured(t_ns, body.v_left, body.v_right))
    return _status(services, name)


@router.get("/{name}/config")
def get_config(name: RobotName, services: ServicesDep, _: Viewer) -> RobotPublic:
    return services.robot_store.get(name)


@router.put("/{name}/config")
def put_config(name: RobotName, body: RobotPublic, services: ServicesDep, _: Admin) -> RobotPublic:
    """Create or replace a robot's configuration and (re)start it; a `sim` robot must exist
    in the virtual site."""
    data = RobotCreate.model_validate({**body.model_dump(), "name": name})
    camera_from_sensor(data.camera, source="camera")  # 422 naming the field before saving
    check_devices(data, services.settings)  # nothing it may not open, a camera that opens
    record = services.robot_store.upsert(data)
    services.robots.apply(record)
    return record


@router.post("/{name}/recording/start")
def start_recording(name: RobotName, services: ServicesDep, _: Operator) -> RecordingStatus:
    """Record this robot's frames, odometry and LED changes (for `irloc replay`)."""
    path = services.recordings.start(name)
    return RecordingStatus(robot=name, recording=True, path=str(path), name=path.name)


@router.post("/{name}/recording/stop")
def stop_recording(name: RobotName, services: ServicesDep, _: Operator) -> RecordingStatus:
    path = services.recordings.stop(name)
    return RecordingStatus(
        robot=name,
        recording=False,
        path=None if path is None else str(path),
        name=None if path is None else path.name,
    )


@router.post("/{name}/black-box", status_code=status.HTTP_201_CREATED)
def save_black_box(name: RobotName, services: ServicesDep, _: Operator) -> BlackBoxPublic:
    """Save the robot's black box now (its last seconds of frames, odometry, LED states and
    poses) as a recording, with trigger `operator`."""
    return BlackBoxPublic.of(services.recordings.save_black_box(name))


@router.get("/{name}/black-boxes")
def list_black_boxes(name: RobotName, services: ServicesDep, _: Viewer) -> list[BlackBoxPublic]:
    """The robot's saved black boxes, oldest first, each with its trigger."""
    services.robots.get(name)  # 404 for an unknown robot
    return [BlackBoxPublic.of(b) for b in services.recordings.black_boxes(name)]
