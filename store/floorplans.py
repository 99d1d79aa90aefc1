"""Each floor's floor plan: one `FloorPlanStore` a floor.

The default floor (`FloorStore.default()`: "0" on a one-floor site) keeps its plan where a
one-floor site always kept it, in the data folder itself; every other floor in
`<data folder>/floors/floor-<floor ID>/` (the prefix: a floor ID may be "..").
"""

from __future__ import annotations

import threading
from pathlib import Path

from store.floorplan import FloorPlanStore
from store.floors import FloorStore


class FloorPlans:
    """The floor plan store of each floor (thread-safe; one store object a floor, so its
    `version` counts every change).

    Args:
        folder: the site's data folder.
        floors: the site's floors (unknown floor IDs are refused naming them).
        default: the default floor's store (the data folder's; None: made here).
    """

    def __init__(
        self, folder: Path, floors: FloorStore, default: FloorPlanStore | None = None
    ) -> None:
        self.folder, self.floors = Path(folder), floors
        self.default = default or FloorPlanStore(self.folder)
        self._stores: dict[str, FloorPlanStore] = {}
        self._lock = threading.Lock()

    def of(self, floor: str | None) -> FloorPlanStore:
        """The plan store of `floor` (None: the default floor's); UnknownFloorError
        (a NotFoundError) for a floor the site does not have."""
        if floor is None:
            return self.default
        self.floors.check(floor, what="floor plan")
        if floor == self.floors.default():
            return self.default
        with self._lock:
            store = self._stores.get(floor)
            if store is None:
                store = self._stores[floor] = FloorPlanStore(
                    self.folder / "floors" / f"floor-{floor}"
                )
            return store
