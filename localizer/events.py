"""What goes into the localizer state machine, and what comes out of it.

The localizer is sans-I/O (as h11 is for HTTP): its owner feeds it these events in time order
through `Localizer.handle(event)` and acts on the outputs it returns. Time is always an integer
count of nanoseconds on the owner's clock (the recording's clock in a replay).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from localizer.pose_quality import ReasonCode

Mode = Literal["identifying", "landmark", "dead_reckoning", "lost"]
MODES: tuple[Mode, ...] = ("identifying", "landmark", "dead_reckoning", "lost")


@dataclass(frozen=True, eq=False)
class FrameObserved:
    """An 8-bit grayscale IR frame, shape (height, width), taken at `t_ns`."""

    t_ns: int
    image: npt.NDArray[np.uint8]


@dataclass(frozen=True, eq=False)
class SpotsObserved:
    """Spots already detected in a frame taken at `t_ns` (a robot that detects on board).

    Attributes:
        pixels: sub-pixel centroids (col, row), shape (N, 2).
        intensities: summed background-free brightness per spot, shape (N,).
        areas: pixel count per spot, shape (N,).
    """

    t_ns: int
    pixels: npt.NDArray[np.float64]
    intensities: npt.NDArray[np.float64]
    areas: npt.NDArray[np.float64]


@dataclass(frozen=True)
class OdometryMeasured:
    """Wheel speeds measured at `t_ns` (v_l, v_r of eq. 6), m/s."""

    t_ns: int
    v_left: float
    v_right: float


@dataclass(frozen=True)
class LedsChanged:
    """The LED state in force from `t_ns` on (confirmed applied by the radio).

    Attributes:
        lit: IDs of the lit landmarks; all others are dark. Ignored when `all_lit`.
        all_lit: every landmark is lit (the normal tracking state).
        changing: landmarks whose LED is being switched from `t_ns` on (a radio command
            was sent, not yet confirmed): their state is unknown in frames taken until a
            later `LedsChanged` no longer lists them. `lit` holds their last confirmed
            state. A recording's `leds.csv` (exact switching times) has none.
    """

    t_ns: int
    lit: frozenset[int] = field(default_factory=frozenset)
    all_lit: bool = False
    changing: frozenset[int] = field(default_factory=frozenset)

    def lit_among(self, landmarks: Iterable[int]) -> frozenset[int]:
        """The lit landmarks, `all_lit` expanded to `landmarks` (every landmark controlled)."""
        return frozenset(int(i) for i in landmarks) if self.all_lit else self.lit

    def surely_dark_as_dark(self) -> LedsChanged:
        """This state without `changing`, as a recording keeps it: a landmark being
        switched counts as lit, so that a landmark written dark is surely dark in every
        frame of that time (one being switched may show either way: written lit, a frame
        may miss its spot, but no frame credits a spot to a dark landmark)."""
        if self.all_lit or not self.changing:
            return LedsChanged(self.t_ns, self.lit, self.all_lit)
        return LedsChanged(self.t_ns, self.lit | self.changing, False)


@dataclass(frozen=True)
class RelocalizeRequested:
    """Forget the pose and identify again (operator's request), at `t_ns`.

    Attributes:
        near: where the robot is thought to be, (x, y, theta) in metres and radians, or
            None: identification then tries the landmarks near it first and a
            map-consistent hand-off may fix the pose at once (as `set_initial_pose`).
        radius_m: how far from `near` the robot may be, metres (a search radius, as
            SICK's `LocInitializeAtPose` takes): 95 % of the prior's mass lies within it.
            None: `FusionConfig.initial_sigma_m`.
    """

    t_ns: int
    near: tuple[float, float, float] | None = None
    radius_m: float | None = None


@dataclass(frozen=True)
class ImuMeasured:
    """An IMU sample at `t_ns`, in the body frame (REP-103: x forward, y left, z up).

    Attributes:
        gyro: angular rate (x, y, z), rad/s; z is the heading rate.
        accel: specific force (x, y, z), m/s^2: about (0, 0, +9.81) at rest on a level
            floor; a tilted body sees gravity's direction tilt with it.
    """

    t_ns: int
    gyro: tuple[float, float, float]
    accel: tuple[float, float, float]


Event = (
    FrameObserved
    | SpotsObserved
    | OdometryMeasured
    | LedsChanged
    | RelocalizeRequested
    | ImuMeasured
)


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """The body pose at `t_ns` (odometry integrated up to it).

    Attributes:
        x, y: metres in the world frame; theta: REP-103 heading in (-pi, pi].
        covariance: of (x, y, theta), shape (3, 3), SI units.
        mode: the localizer's mode when this estimate was made.
        landmark_ids: the landmarks whose spots were used in this frame (empty in dead
            reckoning); a subset of `expected_ids` while tracking (a first fix from
            identification may use landmarks it did not predict).
        expected_ids: the landmarks the localizer expected in view and lit at this frame:
            those it predicted inside the image (from the pose before this frame's fix) among
            the ones surely lit (not being switched), sorted. Empty when it predicted none
            (identifying, lost without a prior). Expected but not in `landmark_ids`: looked
            for and not found, or found and not used (doubt detection reads this).
        quality: 0-1 from `deviation_m` (`pose_quality.quality_from_deviation`); None:
            not computed (an estimate not made by the localizer, e.g. read from a file).
        deviation_m: the radius around (x, y) holding the true position with probability
            0.95 under `covariance`, metres (VDA 5050's `deviationRange`).
        reason: why this is not a landmark fix (None: it is one), `pose_quality.ReasonCode`.
        reason_text: the same as a sentence for people ("" with no reason).
    """

    t_ns: int
    x: float
    y: float
    theta: float
    covariance: npt.NDArray[np.float64]
    mode: Mode
    landmark_ids: tuple[int, ...] = ()
    expected_ids: tuple[int, ...] = ()
    quality: float | None = None
    deviation_m: float | None = None
    reason: ReasonCode | None = None
    reason_text: str = ""


@dataclass(frozen=True)
class NoPose:
    """A frame for which there is no pose yet (identifying, or lost with no prior).

    Attributes:
        reason: why (`pose_quality.ReasonCode`; None: not computed).
        reason_text: the same as a sentence for people.
        quality: always 0; deviation_m: always None (no position).
    """

    t_ns: int
    mode: Mode
    reason: ReasonCode | None = None
    reason_text: str = ""
    quality: float = 0.0
    deviation_m: float | None = None


@dataclass(frozen=True)
class LedRequest:
    """The localizer asks its owner to light exactly `lit`, or, when `all_lit`, every LED
    but those in `dark` (a probe that darkens one landmark while the others stay lit for
    the robots that track them).

    The owner answers with a `LedsChanged` once the radio confirms the change.
    """

    lit: frozenset[int] = field(default_factory=frozenset)
    all_lit: bool = False
    dark: frozenset[int] = field(default_factory=frozenset)

    def __post_init__(self) -> None:
        if self.dark and not self.all_lit:
            raise ValueError("LedRequest: `dark` only goes with all_lit=True")


Output = PoseEstimate | NoPose | LedRequest
