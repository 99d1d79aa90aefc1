"""What the identification wizard tells its user (docs/commissioning.md): plain text from
plain values, so `commissioning.wizard` stays the state machine. Positions in metres, map
frame, two decimals (a measurement three)."""

from __future__ import annotations

from dataclasses import dataclass

from commissioning.types import Candidate, MapLandmark
from commissioning.wizard_messages import Measurement
from localizer.events import PoseEstimate


def what(candidate: Candidate, index: int, total: int) -> str:
    """The candidate and its place in the queue: "Landmark 12 (1 of 3)"."""
    n = f"({index + 1} of {total})"
    if candidate.radio is not None:
        return f"New radio {candidate.radio} (to be landmark {candidate.landmark_id}) {n}"
    return f"Landmark {candidate.landmark_id} {n}"


def waiting_prompt(
    head: str,
    landmark_id: int,
    blockers: tuple[str, ...],
    waited_s: float,
    *,
    min_fix_landmarks: int,
    wait_fix_s: float,
) -> str:
    """Why the wizard does not darken the landmark yet; after `wait_fix_s` it asks."""
    names = ", ".join(blockers)
    text = (
        f"{head}: darkening it would cost {names} its landmark fix (it tracks with landmark "
        f"{landmark_id} and fewer than {min_fix_landmarks} others): waiting for {names} to "
        f"move on ({waited_s:.0f} s)"
    )
    if waited_s >= wait_fix_s:
        text += "; switch anyway (it falls back to dead reckoning for a moment), or skip"
    return text


def never_switched_prompt(head: str, want_on: bool) -> str:
    """The target's LED was never confirmed in the wanted state."""
    state = "lit" if want_on else "dark"
    return (
        f"{head}: its LED was never confirmed {state} (does its radio answer?): skip it, or "
        "type its position by hand"
    )


@dataclass(frozen=True)
class NoSpot:
    """Why no sample came, as the wizard sees it (what `no_spot_prompt` words).

    Attributes:
        robot: the measuring robot; pose: its latest estimate (None: none yet).
        known: the landmark's map record (None: a new radio, `radio` its address).
        in_view: the landmark's map position is in the robot's view now.
        reflections: more than one spot followed the target in most lit frames.
        flickering: where the last spot that came and went out of step with the target was
            (x, y), metres; None: none did.
        min_cycles: how many lit phases a spot must follow the target through.
    """

    robot: str
    pose: PoseEstimate | None
    known: MapLandmark | None
    radio: str | None
    in_view: bool
    reflections: bool
    flickering: tuple[float, float] | None
    min_cycles: int


def no_spot_prompt(s: NoSpot) -> str:
    """What to move when no spot followed the target: the robot (under it, to where the
    radio hangs, or a little: reflections), or skip it."""
    robot, pose = s.robot, s.pose
    if pose is None or pose.mode != "landmark":
        return (
            f"{robot} has no landmark fix, and measuring needs one: drive {robot} where it "
            "sees at least three lit landmarks"
        )
    where = f"{robot} is at ({pose.x:.2f}, {pose.y:.2f})"
    if s.reflections:
        return (
            f"more than one spot switches with it in {robot}'s view (reflections?): drive "
            f"{robot} a little to another place"
        )
    flicker = ""
    if s.flickering is not None:
        fx, fy = s.flickering
        flicker = (
            f"; a spot at ({fx:.2f}, {fy:.2f}) comes and goes out of step with it (a "
            f"reflection or a faint light, not its LED: a spot must follow the LED through "
            f"{s.min_cycles} of its cycles), so it is not measured"
        )
    if s.known is None:
        return (
            f"no spot follows radio {s.radio}'s LED in {robot}'s view ({where}){flicker}: "
            f"keep it blinking and drive {robot} to where the radio hangs, or skip it"
        )
    lm = s.known
    d = ((lm.x - pose.x) ** 2 + (lm.y - pose.y) ** 2) ** 0.5
    if not s.in_view:
        return (
            f"landmark {lm.id}'s map position ({lm.x:.2f}, {lm.y:.2f}) is not in {robot}'s "
            f"view ({where}, {d:.1f} m away): drive {robot} under it{flicker}"
        )
    if s.flickering is not None:
        return (
            f"no spot follows landmark {lm.id}'s LED in {robot}'s view although its map "
            f"position is in view ({where}, {d:.1f} m away){flicker}: keep it blinking and "
            f"drive {robot} right under it, or skip it"
        )
    return (
        f"no spot switches with landmark {lm.id} in {robot}'s view although its map "
        f"position is in view ({where}): its LED may be dead or it hangs elsewhere; drive "
        f"{robot} around where it may be, or skip it"
    )


def measuring_prompt(
    head: str, measurement: Measurement | None, samples: int, no_spot: str | None
) -> str:
    """The measurement so far; `no_spot` (from `no_spot_prompt`) once it has waited long
    enough without a sample, else None."""
    if measurement is not None:
        x, y, z = measurement.position
        return (
            f"{head}: at ({x:.3f}, {y:.3f}, {z:.3f}) m, {measurement.samples} frames agree "
            f"within {100 * measurement.spread_m:.1f} cm; {measurement.plausibility.note}"
        )
    if samples:
        return f"{head}: measuring ({samples} frames, not yet agreeing)"
    if no_spot is None:
        return f"{head}: measuring"
    return f"{head}: {no_spot}"
