"""The landmarks' light and energy: the LED planner, the radios' wake window, cells and duty."""
