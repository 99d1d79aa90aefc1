"""A simulated drive written as a recording folder: `sim.offline` into `recording`'s writer.

`sim` and `recording` do not import each other (docs/architecture.md); this is where the
two meet, for `irloc simulate`, the benchmarks and the tests.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

from localizer.camera import CameraModel
from localizer.events import LedsChanged
from localizer.robot import RobotGeometry
from recording.writer import RecordingWriter
from sim import offline
from sim.cameras import Lens
from sim.offline import SimulationSummary, SweepConfig
from sim.scenario import Scenario


def simulate_recording(
    scenario: Scenario,
    out_dir: Path | str,
    *,
    seed: int | None = None,
    duration_s: float | None = None,
    lens: Lens | None = None,
    robot: str | None = None,
    sweep: SweepConfig | None = None,
    led_program: Callable[[int], Sequence[LedsChanged]] | None = None,
    progress: Callable[[float], None] | None = None,
) -> SimulationSummary:
    """Write a recording (and groundtruth.csv) of one robot of a scenario into `out_dir`
    (created); the other arguments are `sim.offline.simulate_recording`'s.

    Raises:
        ValueError: unknown robot name.
    """

    def open_writer(
        camera: CameraModel, robot_geometry: RobotGeometry, records: Iterable[Mapping[str, object]]
    ) -> RecordingWriter:
        return RecordingWriter(out_dir, camera, robot_geometry, records)

    return offline.simulate_recording(
        scenario,
        open_writer,
        seed=seed,
        duration_s=duration_s,
        lens=lens,
        robot=robot,
        sweep=sweep,
        led_program=led_program,
        progress=progress,
    )
