"""Whether a robot's view still fits its floor's map, frame by frame: the guard that keeps
a robot that changed floors untold from publishing poses on the old floor's map.

A robot's view stops fitting when, for `unfit_after_s`, its localizer tracked by dead
reckoning while it expected landmarks of its map in view, and fixed on none: the ceiling
it sees is not the one its map says (another floor, or the lift's cabin). Frames of an
identification (`identifying`, `lost`) carry no pose to withhold and neither start nor
break such a run. Its floor is then *unknown*: its poses are withheld
(published without a position, `floor_unknown`), and the site's floor watch tries its
view on the other floors (`live.floor_watch`; a robot agent withholds its own poses the
same way, `agent.floors`). The floor is known again when the robot is told its floor (a
move, or an accepted proposal), or when it has held landmark fixes on its own map for
`own_fix_hold_s` (a moment's fix on a ceiling that only looks like its own, by the lift's
door, is not enough).

Pure and sans-I/O: `observe` takes each frame's localizer output; times are the frames'.
"""

from __future__ import annotations

from dataclasses import dataclass

from localizer.events import NoPose, PoseEstimate

NS = 1_000_000_000


@dataclass(frozen=True)
class FloorFitConfig:
    """When a robot's floor becomes unknown and when it is known again.

    Attributes:
        unfit_after_s: seconds of frames (the robot's clock) of dead reckoning with
            landmarks expected in view before the floor is unknown.
        own_fix_hold_s: seconds of landmark fixes on its own map, without a frame between
            them that is no fix, before an unknown floor is known again.
    """

    unfit_after_s: float = 1.0
    own_fix_hold_s: float = 3.0

    def __post_init__(self) -> None:
        if not (self.unfit_after_s > 0 and self.own_fix_hold_s >= 0):
            raise ValueError(
                f"floor fit: unfit_after_s must be > 0 and own_fix_hold_s >= 0 (got "
                f"{self.unfit_after_s}, {self.own_fix_hold_s})"
            )


class FloorFit:
    """One robot's view against its floor's map (see the module docstring)."""

    def __init__(self, config: FloorFitConfig | None = None) -> None:
        self.config = config or FloorFitConfig()
        self.unknown = False
        """True while the robot's floor is unknown (its poses are withheld)."""
        self.unknown_since_ns: int | None = None
        """The frame time the floor became unknown (None while it is known)."""
        self.withheld = 0
        """Poses withheld so far."""
        self.last_estimate: PoseEstimate | None = None
        """The latest pose on its floor's map, withheld or not (where a trial on another
        floor starts: the floors' frames are stacked)."""
        self._misfit_since: int | None = None
        self._fix_since: int | None = None

    def observe(self, out: PoseEstimate | NoPose) -> bool:
        """Take one frame's localizer output; True when its pose must be withheld."""
        cfg, t = self.config, out.t_ns
        if isinstance(out, PoseEstimate):
            self.last_estimate = out
        if isinstance(out, PoseEstimate) and out.mode == "landmark":
            self._misfit_since = None
            if self.unknown:
                self._fix_since = t if self._fix_since is None else self._fix_since
                if t - self._fix_since >= cfg.own_fix_hold_s * NS:
                    self.known()
        else:
            self._fix_since = None
            if isinstance(out, PoseEstimate) and out.mode == "dead_reckoning" and out.expected_ids:
                if self._misfit_since is None:
                    self._misfit_since = t
                elif not self.unknown and t - self._misfit_since >= cfg.unfit_after_s * NS:
                    self.unknown, self.unknown_since_ns = True, t
        if self.unknown and isinstance(out, PoseEstimate):
            self.withheld += 1
        return self.unknown

    def known(self) -> None:
        """The robot's floor is known (told, or its own map held): poses go out again."""
        self.unknown, self.unknown_since_ns = False, None
        self._misfit_since = self._fix_since = None
