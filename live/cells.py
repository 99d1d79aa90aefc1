"""Cells replaced: staff put fresh cells into a landmark; its battery estimate starts over.

The replacement is an event (`cells_replaced`, with who did it) stored before anything else:
from then on the landmark's battery status (`LedsAndRadio.battery`: the latest reading, the
days-left trend, and the energy model's days at the schedule's duty, `live.leds.status`)
reads only the readings taken after it (a trend across the swap would read as a charging
battery), the radio gateway forgets the old readings and its low-battery latch (a new low
reading is reported again), and the supply is read at once when the radio answers. On the
simulated site the virtual landmark gets its fresh cells too (there is no one to put them in).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

from live.facades import BatteryStatus
from rf_gateway.errors import RfGatewayError
from store.errors import UnavailableError

if TYPE_CHECKING:
    from live.services import SiteServices

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CellsReplaced:
    """What a replacement left.

    Attributes:
        battery: the landmark's battery status after it (a reading when the radio answered).
        read: whether the supply was read after the swap; why_not: the radio's reason if not.
    """

    battery: BatteryStatus
    read: bool
    why_not: str | None = None


async def replace_cells(services: SiteServices, landmark_id: int, *, actor: str) -> CellsReplaced:
    """Record that `landmark_id` has fresh cells (run on the server's loop); NotFoundError
    for a landmark not in the map (nothing stored)."""
    services.map.get(landmark_id)
    services.events.emit(
        "cells_replaced",
        f"landmark {landmark_id}: cells replaced by {actor}",
        landmark_id=landmark_id,
        data={"actor": actor},
    )
    services.events.flush()  # stored before the status below reads past it
    sim = services.virtual_site
    if sim is not None and landmark_id in sim.world.landmarks:
        # the virtual site has no technician: its landmark gets the fresh cells here
        sim.world.replace_cells(landmark_id)
    gw = services.leds.gateway
    if gw is not None:
        gw.batteries.forget(landmark_id)
    why_not = None
    try:
        await services.leds.read_battery(landmark_id)
    except (RfGatewayError, UnavailableError, TimeoutError) as exc:
        why_not = str(exc) or type(exc).__name__
        log.info("landmark %d: supply not read after the swap: %s", landmark_id, why_not)
    return CellsReplaced(services.leds.battery(landmark_id), why_not is None, why_not)
