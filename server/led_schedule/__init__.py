"""The scheduled LED policy: light only what the robots need (`docs/server.md`)."""

from server.led_schedule.policy import LedPlan, RobotState, ScheduleConfig, plan_leds
from server.led_schedule.runtime import LedScheduler

__all__ = ["LedPlan", "LedScheduler", "RobotState", "ScheduleConfig", "plan_leds"]
