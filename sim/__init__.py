"""The virtual site: landmarks, radio, robots and upward IR cameras (`docs/sim.md`)."""

from sim.live import LiveSite, SensorSample
from sim.radio import SimRadio
from sim.render import ExtendedSource, RenderConfig, render_frame
from sim.scenario import SCENARIOS, Scenario, load_scenario

__all__ = [
    "SCENARIOS",
    "ExtendedSource",
    "LiveSite",
    "RenderConfig",
    "Scenario",
    "SensorSample",
    "SimRadio",
    "load_scenario",
    "render_frame",
]
