"""The landmark map as the localizer sees it: IDs and 3D positions in the world frame, and
for each landmark what the map states of it: its position's uncertainty, whether it can
blink (an LED on the radio) or not (a passive light: a ceiling panel, an LED whose radio is
out), and its size (an LED is a point; a panel is not)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from localizer.types import BoolArray, FloatArray, IntArray


class DuplicateLandmarkError(ValueError):
    """Two landmarks of one map share an ID."""


@dataclass(frozen=True, eq=False)
class LandmarkMap:
    """Landmark IDs and positions.

    Attributes:
        ids: landmark IDs, shape (N,), unique integers.
        positions: LED positions in the world frame, metres, shape (N, 3).
        sigmas: each position's 1-sigma uncertainty as the map states it (a survey's
            `sigma_m`), metres, shape (N,); NaN where not stated, None when none is (the
            localizer then takes `PixelNoiseConfig.survey_sigma_m` for every landmark).
        passive: whether each landmark is passive (never switched: identified by geometry
            alone, `localizer.passive_identification`), shape (N,); None: none is.
        sizes: each landmark's extent (a light's longest side or diameter), metres, shape
            (N,); 0 for a point (an LED); None: all are points.
    """

    ids: IntArray
    positions: FloatArray
    sigmas: FloatArray | None = None
    passive: BoolArray | None = None
    sizes: FloatArray | None = None
    _index: dict[int, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=np.int64).reshape(-1)
        pos = np.asarray(self.positions, dtype=np.float64).reshape(-1, 3)
        if len(ids) != len(pos):
            raise ValueError(f"landmark map: {len(ids)} ids but {len(pos)} positions")
        if not np.all(np.isfinite(pos)):
            bad = int(ids[~np.all(np.isfinite(pos), axis=1)][0])
            raise ValueError(f"landmark map: landmark {bad} has a non-finite coordinate")
        index: dict[int, int] = {}
        for i, lid in enumerate(ids.tolist()):
            if lid in index:
                raise DuplicateLandmarkError(f"landmark map: duplicate landmark id {lid}")
            index[lid] = i
        if self.sigmas is not None:
            sig = np.asarray(self.sigmas, dtype=np.float64).reshape(-1)
            if len(sig) != len(ids):
                raise ValueError(f"landmark map: {len(ids)} ids but {len(sig)} sigmas")
            if np.any(sig[np.isfinite(sig)] < 0) or np.any(np.isinf(sig)):
                raise ValueError("landmark map: a sigma is negative or infinite")
            sig.setflags(write=False)
            object.__setattr__(self, "sigmas", sig)
        if self.passive is not None:
            flags = np.asarray(self.passive, dtype=bool).reshape(-1)
            if len(flags) != len(ids):
                raise ValueError(f"landmark map: {len(ids)} ids but {len(flags)} passive flags")
            flags.setflags(write=False)
            object.__setattr__(self, "passive", flags)
        if self.sizes is not None:
            size = np.asarray(self.sizes, dtype=np.float64).reshape(-1)
            if len(size) != len(ids):
                raise ValueError(f"landmark map: {len(ids)} ids but {len(size)} sizes")
            if not np.all(np.isfinite(size)) or np.any(size < 0):
                raise ValueError("landmark map: a size is negative or not finite")
            size.setflags(write=False)
            object.__setattr__(self, "sizes", size)
        ids.setflags(write=False)
        pos.setflags(write=False)
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "_index", index)

    def __len__(self) -> int:
        return len(self.ids)

    def __contains__(self, landmark_id: object) -> bool:
        return landmark_id in self._index

    def index_of(self, landmark_id: int) -> int:
        """Row of `landmark_id` in `ids`/`positions`; KeyError names an unknown ID."""
        try:
            return self._index[int(landmark_id)]
        except KeyError:
            raise KeyError(f"unknown landmark id {landmark_id}") from None

    def sigma_at(self, row: int) -> float | None:
        """The stated 1-sigma uncertainty of the landmark in `row`, metres (None: not stated)."""
        if self.sigmas is None:
            return None
        v = float(self.sigmas[row])
        return v if math.isfinite(v) else None

    def position(self, landmark_id: int) -> FloatArray:
        """World position of one landmark, shape (3,)."""
        position: FloatArray = self.positions[self.index_of(landmark_id)]
        return position

    @classmethod
    def from_records(
        cls, records: Iterable[Mapping[str, Any]], *, source: str = "map"
    ) -> LandmarkMap:
        """Build a map from `{"id", "x", "y", "z"}` records (map.json's `landmarks`), each
        with optional `sigma_m` (metres), `passive` (true: never switched) and `size_m`
        (metres; 0 or absent: a point).

        Raises:
            ValueError: naming `source`, the record index and the bad key or value.
        """
        ids: list[int] = []
        pos: list[tuple[float, float, float]] = []
        sigmas: list[float] = []
        passive: list[bool] = []
        sizes: list[float] = []
        for i, rec in enumerate(records):
            if not isinstance(rec, Mapping):
                raise ValueError(f"{source}: landmark #{i} is not an object")
            if "id" not in rec:
                raise ValueError(f"{source}: landmark #{i} has no 'id'")
            lid = rec["id"]
            if isinstance(lid, bool) or not isinstance(lid, int):
                raise ValueError(f"{source}: landmark #{i}: 'id' must be an integer, got {lid!r}")
            xyz = []
            for key in ("x", "y", "z"):
                if key not in rec:
                    raise ValueError(f"{source}: landmark {lid}: missing '{key}'")
                v = rec[key]
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                    raise ValueError(
                        f"{source}: landmark {lid}: '{key}' must be a finite number, got {v!r}"
                    )
                xyz.append(float(v))
            if lid in ids:
                raise DuplicateLandmarkError(f"{source}: duplicate landmark id {lid}")
            ids.append(lid)
            pos.append((xyz[0], xyz[1], xyz[2]))
            sigmas.append(_optional_metres(rec, "sigma_m", lid, source, math.nan))
            sizes.append(_optional_metres(rec, "size_m", lid, source, 0.0))
            flag = rec.get("passive", False)
            if not isinstance(flag, bool):
                raise ValueError(
                    f"{source}: landmark {lid}: 'passive' must be true or false, got {flag!r}"
                )
            passive.append(flag)
        sig = np.array(sigmas, dtype=np.float64)
        return cls(
            np.array(ids, dtype=np.int64),
            np.array(pos, dtype=np.float64).reshape(-1, 3),
            sig if np.any(np.isfinite(sig)) else None,
            np.array(passive, dtype=bool) if any(passive) else None,
            np.array(sizes, dtype=np.float64) if any(sizes) else None,
        )

    def to_records(self) -> list[dict[str, float | int | bool]]:
        """The inverse of `from_records`."""
        out: list[dict[str, float | int | bool]] = []
        for row, (i, p) in enumerate(zip(self.ids, self.positions, strict=True)):
            rec: dict[str, float | int | bool] = {
                "id": int(i),
                "x": float(p[0]),
                "y": float(p[1]),
                "z": float(p[2]),
            }
            sigma = self.sigma_at(row)
            if sigma is not None:
                rec["sigma_m"] = sigma
            if self.passive is not None and self.passive[row]:
                rec["passive"] = True
            if self.sizes is not None and self.sizes[row] > 0:
                rec["size_m"] = float(self.sizes[row])
            out.append(rec)
        return out


def _optional_metres(
    rec: Mapping[str, Any], key: str, lid: int, source: str, default: float
) -> float:
    """An optional non-negative length of a record (`default` when absent or null)."""
    v = rec.get(key)
    if v is None:
        return default
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
        raise ValueError(
            f"{source}: landmark {lid}: '{key}' must be a non-negative number of metres, got {v!r}"
        )
    return float(v)
