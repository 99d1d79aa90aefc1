"""The virtual site: landmarks, radio, robots and upward IR cameras (`docs/sim.md`)."""

from sim.radio import SimRadio
from sim.render import ExtendedSource, RenderConfig, render_frame
from sim.scenario import SCENARIOS, Scenario, load_scenario
from sim.virtual_site import SensorSample, VirtualSite

__all__ = [
    "SCENARIOS",
    "ExtendedSource",
    "RenderConfig",
    "Scenario",
    "SensorSample",
    "SimRadio",
    "VirtualSite",
    "load_scenario",
    "render_frame",
]
