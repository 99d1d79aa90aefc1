"""The identification wizard's tuning (docs/commissioning.md): one frozen dataclass, units
in the field docs."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class WizardConfig:
    """The wizard's tuning.

    Attributes:
        dark_s: the target's LED is held dark this long per cycle, seconds.
        lit_s: ... and lit this long between, seconds.
        settle_s: a frame counts once taken this long after its LED state was confirmed, s.
        resend_s: an LED state the wizard wants and does not see is asked for again after
            this long (a robot's own LED request may have replaced it), seconds.
        match_m: a spot of the lit frame with no spot of the dark frame within this
            (horizontally, on the ceiling) is a candidate for the target's, metres.
        min_cycles: a candidate is the target's once it followed its LED through this many
            lit phases and the dark ones between: present in every frame that would have
            seen it while lit, absent in every one while dark.
        agree_m: samples agree when within this of their median (horizontally), metres.
        min_agreeing: Confirm is offered once this many successive samples agree.
        far_m: a measurement farther than this from the map's position is flagged, metres.
        min_fix_landmarks: a tracking robot keeps its fix with this many landmarks.
        wait_fix_s: after waiting this long for robots to free a landmark, the wizard asks
            whether to switch it anyway, seconds.
        no_spot_s: after measuring this long without a sample, it says what to move, s.
        max_sigma_m: the measuring robot's 1-sigma position error must be at most this, m.
        keep_s: frames and LED states kept for following a candidate, seconds: a little
            over `min_cycles` + 1 cycles of `dark_s + lit_s`, so that a robot that delivers
            few frames (a loaded computer) still has `min_cycles` lit phases in them.
        max_keep_s: frames of the last 2 `min_cycles` phases of the target's LED are kept
            longer than `keep_s` (the LED coordinator stretches a phase while robots take
            their turns), up to this, seconds.
        margin_px: a map position this far inside the image border counts as in view, px.
    """

    dark_s: float = 0.5
    lit_s: float = 0.6
    settle_s: float = 0.05
    resend_s: float = 0.4
    match_m: float = 0.15
    min_cycles: int = 2
    agree_m: float = 0.03
    min_agreeing: int = 5
    far_m: float = 0.5
    min_fix_landmarks: int = 3
    wait_fix_s: float = 10.0
    no_spot_s: float = 4.0
    max_sigma_m: float = 0.05
    keep_s: float = 3.4
    max_keep_s: float = 12.0
    margin_px: float = 10.0
