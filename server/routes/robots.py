"""`/robots`: list, pose, relocalize, configuration, wheel speeds, recordings."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Response, status
from pydantic import BaseModel, Field

from live.agent_runner import AgentRunner, agent_fields
from live.black_box import BlackBoxRecording
from live.poses import PosePublic, pose_json
from localizer.camera import camera_from_sensor
from localizer.events import Mode, OdometryMeasured
from server.auth import Admin, Operator, Viewer
from server.deps import RobotName, ServicesDep
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


class WheelSpeeds(BaseModel):
    """Wheel speeds measured now (or at `t_ns` on the site clock), m/s."""

    v_left: float = Field(ge=-20, le=20)
    v_right: float = Field(ge=-20, le=20)
    t_ns: int | None = Field(default=None, ge=0, le=2**62)


class RecordingStatus(BaseModel):
    robot: str
    recording: bool
    path: str | None = None


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
        return cls(robot=b.robot, trigger=b.trigger, reason=b.reason, t_ns=b.t_ns,
                   saved_at=b.saved_at, bytes=b.bytes, path=str(b.path))  # fmt: skip


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
    return Response(pose_json(name, runner.mode, runner.latest), media_type="application/json")


class PoseHint(BaseModel):
    """Where the robot is thought to be (world frame, REP-103 heading)."""

    x: float = Field(allow_inf_nan=False, ge=-1e4, le=1e4, description="metres")
    y: float = Field(allow_inf_nan=False, ge=-1e4, le=1e4, description="metres")
    theta: float = Field(0.0, allow_inf_nan=False, ge=-7.0, le=7.0, description="radians")


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
    record = services.robot_store.upsert(data)
    services.robots.apply(record)
    return record


@router.post("/{name}/recording/start")
def start_recording(name: RobotName, services: ServicesDep, _: Operator) -> RecordingStatus:
    """Record this robot's frames, odometry and LED changes (for `irloc replay`)."""
    path = services.recordings.start(name)
    return RecordingStatus(robot=name, recording=True, path=str(path))


@router.post("/{name}/recording/stop")
def stop_recording(name: RobotName, services: ServicesDep, _: Operator) -> RecordingStatus:
    path = services.recordings.stop(name)
    return RecordingStatus(robot=name, recording=False, path=None if path is None else str(path))


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
