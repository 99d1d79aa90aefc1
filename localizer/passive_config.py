"""Tuning of passive landmarks (lights that cannot blink): `PassiveConfig`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from localizer.landmark_map import LandmarkMap

PassiveMode = Literal["off", "auto", "all"]


@dataclass(frozen=True)
class PassiveConfig:
    """Passive landmarks: when and how they are identified by geometry.

    Attributes:
        mode: "auto": by geometry when every landmark of the map is flagged passive
            (map.json's `passive`); "all": every landmark is passive (the site's radio is
            out, or its landmarks are its own lights); "off": never.
        landmark_sigma_m: a passive light's 1-sigma position error where the map states
            none, metres (a panel's centroid: the survey, the diffuser, the perspective).
        every_s: a one-frame constellation match at most this often, seconds.
        view_side_m: map triangles are indexed up to this side, metres (the widest view of
            the ceiling the camera has; longer spot triangles are not formed).
        max_elongation: the detector keeps blobs up to this elongation (a strip light
            seen obliquely).
        outlier_sigma: a verified fix's pairs reproject within this many pixel sigmas.

    The matcher's own tuning is `LocalizerConfig.constellation`.
    """

    mode: PassiveMode = "auto"
    landmark_sigma_m: float = 0.05
    every_s: float = 0.25
    view_side_m: float = 12.0
    max_elongation: float = 5.0
    outlier_sigma: float = 4.0

    def __post_init__(self) -> None:
        if self.mode not in ("off", "auto", "all"):
            raise ValueError(f"PassiveConfig: mode must be off, auto or all, got {self.mode!r}")
        for name in ("landmark_sigma_m", "view_side_m", "max_elongation", "outlier_sigma"):
            if not getattr(self, name) > 0:
                raise ValueError(f"PassiveConfig: {name} must be > 0")

    def applies_to(self, landmark_map: LandmarkMap) -> bool:
        """Whether the map's landmarks are identified by geometry under this setting."""
        if self.mode == "all":
            return len(landmark_map) > 0
        flags = landmark_map.passive
        return self.mode == "auto" and flags is not None and bool(np.all(flags))


__all__ = ["PassiveConfig", "PassiveMode"]
