"""`/keys` (admin), `/radio` (state, discovery)."""

from __future__ import annotations

from fastapi import APIRouter, Path, Response, status
from pydantic import BaseModel, Field

from server.auth import Admin, Operator, Viewer
from server.deps import ServicesDep
from store.models import ApiKeyPublic, Role

router = APIRouter(tags=["admin"])


class KeyCreate(BaseModel):
    role: Role
    name: str = Field(default="", max_length=200)


class KeyCreated(BaseModel):
    key: str = Field(description="shown only now; store it")
    record: ApiKeyPublic


class RadioState(BaseModel):
    state: str
    landmarks: int
    unreachable: list[int]
    lit: list[int]
    waiting_requests: int


class Discovered(BaseModel):
    address: str
    node_id: str


@router.get("/keys")
def list_keys(services: ServicesDep, _: Admin) -> list[ApiKeyPublic]:
    return services.keys.list()


@router.post("/keys", status_code=status.HTTP_201_CREATED)
def create_key(body: KeyCreate, services: ServicesDep, _: Admin) -> KeyCreated:
    key, record = services.keys.create(body.role, body.name)
    return KeyCreated(key=key, record=record)


@router.delete("/keys/{key_id}", status_code=status.HTTP_204_NO_CONTENT)
def revoke_key(services: ServicesDep, _: Admin, key_id: int = Path(ge=0, le=2**31)) -> Response:
    services.keys.revoke(key_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/radio")
async def radio_state(services: ServicesDep, _: Viewer) -> RadioState:
    gw = services.leds.gateway
    coord = services.leds.coordinator
    return RadioState(
        state="absent" if gw is None else str(gw.transport.state),
        landmarks=0 if gw is None else len(gw.landmarks),
        unreachable=[] if gw is None else sorted(gw.unreachable),
        lit=sorted(services.leds.lit()),
        waiting_requests=0 if coord is None else coord.waiting,
    )


@router.post("/radio/discover")
async def discover(services: ServicesDep, _: Operator) -> list[Discovered]:
    """Radios that answer node discovery and are not in the map."""
    radios = await services.leds.discover()
    return [Discovered(address=r.address, node_id=r.node_id) for r in radios]
