"""The scheduled LED policy: light only what the robots need (`docs/server.md`)."""

from lighting.policy import LedPlan, RobotState, ScheduleConfig, plan_leds
from live.leds.runtime import LedScheduler

__all__ = ["LedPlan", "LedScheduler", "RobotState", "ScheduleConfig", "plan_leds"]
