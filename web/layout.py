"""Fit one browser's panel to its window: a phone gets the hall, a wide screen a wider panel.

viser reports each browser's canvas size with its camera. On a phone (narrow window) the
panel covered most of the hall: the viewer folds every panel into one "Panels" folder there
(`wait_for_width` tells it the size when it builds the panel). On a wide screen (1920 px)
the default panel stayed 240 px wide and wrapped every table: it gets `wide_panel_px`,
applied when the size is first known and whenever the window becomes wide.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Literal

import viser

WindowClass = Literal["phone", "desktop", "wide"]


@dataclass(frozen=True)
class LayoutConfig:
    """Window classes by canvas width, CSS pixels, and the wide panel's width."""

    phone_max_px: int = 700
    wide_min_px: int = 1600
    wide_panel_px: int = 440


def window_class(width_px: int, config: LayoutConfig | None = None) -> WindowClass:
    """ "phone" up to `phone_max_px`, "wide" from `wide_min_px`, else "desktop"."""
    cfg = config or LayoutConfig()
    if width_px <= cfg.phone_max_px:
        return "phone"
    if width_px >= cfg.wide_min_px:
        return "wide"
    return "desktop"


def wait_for_width(client: viser.ClientHandle, *, timeout_s: float) -> int:
    """The browser's canvas width in CSS pixels once its first camera message came, or 0
    after `timeout_s` (call from a worker thread, e.g. viser's connect callback)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return int(client.camera.image_width)
        except AssertionError:  # viser: no camera message yet
            if time.monotonic() > deadline:
                return 0
            time.sleep(0.02)


class ClientLayout:
    """Keeps one browser's panel fitted to its window (`viser` camera updates)."""

    def __init__(self, client: viser.ClientHandle, config: LayoutConfig | None = None) -> None:
        self.client, self.config = client, config or LayoutConfig()
        self.applied: WindowClass | None = None
        self._lock = threading.Lock()
        client.camera.on_update(self._on_camera)

    def _on_camera(self, camera: viser.CameraHandle) -> None:
        self.fit(camera.image_width)

    def fit(self, width_px: int) -> WindowClass | None:
        """Apply the layout of a `width_px` wide window (once per class); the class."""
        if width_px <= 0:
            return None
        kind = window_class(width_px, self.config)
        with self._lock:
            if kind == self.applied:
                return kind
            self.applied = kind
        panel = self.client.gui.main_panel
        if kind == "wide":
            panel.set_width(self.config.wide_panel_px)
        return kind
