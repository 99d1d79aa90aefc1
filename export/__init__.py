"""Opening irloc's data where robot people look at it: MCAP for Foxglove and ROS 2
(`irloc export`) and the validation report (`irloc report`), from a recording.

Import contract: `export` imports `localizer` and `recording` (and nothing else of irloc);
nothing of irloc imports `export` except the `irloc` entry point (`irloc/cli.py`).
"""
