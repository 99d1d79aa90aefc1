"""History playback in the viewer over a week of kept poses (a real SQLite file): the trail
is bounded, coloured by mode or quality and broken at gaps, the ghost follows the slider,
the heatmap counts every pose."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import viser

from store.db import make_engine, migrate
from store.models import PoseRecord
from store.zones import PoseHistory
from web.colors import mode_color
from web.panels.playback import PlaybackPanel, quality_color, trail_segments


def test_a_week_plays_back_in_a_bounded_trail_with_a_ghost_and_a_heatmap(
    server: viser.ViserServer, tmp_path: Path
) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    history = PoseHistory(engine)
    now = datetime(2026, 12, 7, 12, tzinfo=UTC)
    n = 4_000  # every 150 s over a week, a circle of 3 m
    k = np.arange(n)
    a = 2 * np.pi * k / 400
    history.add([
        PoseRecord(robot="r1", t=now - timedelta(seconds=150 * (n - i)), t_ns=int(i),
                   x=3 * np.cos(a[i]), y=3 * np.sin(a[i]), theta=a[i] + np.pi / 2,
                   sigma_m=0.01 if i % 2 else 0.2,
                   mode="landmark" if i < n - 20 else "dead_reckoning")
        for i in range(n)
    ])  # fmt: skip
    history.add([PoseRecord(robot="r2", t=now - timedelta(minutes=5), t_ns=0, x=9.0, y=9.0,
                            theta=0.0, mode="landmark")])  # fmt: skip
    panel = PlaybackPanel(server, history, lambda: ["r1", "r2"], lambda t, b: None,
                          max_points=1000, now=lambda: now)  # fmt: skip
    panel.gui_window.value = "last 7 days"  # type: ignore[misc]
    panel.gui_heat.value = True  # type: ignore[misc]
    text = panel.load()
    assert len(panel.poses) == 1000 and "every 4th of 4000" in text
    assert "heatmap: 4001 poses" in text  # every pose of every robot, not the thinned
    assert panel.gui_time.max == 999 and not panel.gui_time.disabled
    ghost = panel.scrub(0)
    assert ghost is not None and ghost.t_ns == 0 and "landmarks" in panel.gui_at.content
    assert panel.scrub(10_000) is panel.poses[-1]  # clamped
    assert "dead reckoning" in panel.gui_at.content
    panel.gui_window.value = "last 15 minutes"  # type: ignore[misc]
    panel.gui_heat.value = False  # type: ignore[misc]
    assert "6 poses (every pose)" in panel.load()  # 15 min at one pose every 150 s
    panel.gui_robot.value = "r2"  # type: ignore[misc]
    panel.gui_window.value = "last 15 minutes"  # type: ignore[misc]
    assert "1 poses" in panel.load()
    panel.clear()
    assert panel.poses == [] and panel.gui_time.disabled
    engine.dispose()


def test_trail_colours_and_gaps() -> None:
    t0 = datetime(2026, 12, 7, tzinfo=UTC)
    poses = [
        PoseRecord(robot="r1", t=t0 + timedelta(seconds=s), t_ns=0, x=float(s), y=0.0,
                   theta=0.0, sigma_m=sig, mode=mode)
        for s, sig, mode in ((0, 0.01, "landmark"), (1, 0.05, "dead_reckoning"),
                             (2, 0.2, "landmark"), (60, 0.01, "landmark"))
    ]  # fmt: skip
    seg, colors = trail_segments(poses, "mode", max_gap_s=10.0)
    assert seg.shape == (2, 2, 3)  # the 58 s gap is not joined
    assert tuple(colors[0, 0]) == mode_color("landmark")
    assert tuple(colors[1, 0]) == mode_color("dead_reckoning")
    _, q = trail_segments(poses, "quality", max_gap_s=10.0)
    assert tuple(q[0, 0]) == quality_color(0.01) == (40, 200, 40)  # green
    assert tuple(q[1, 0]) == quality_color(0.05)
    assert quality_color(0.2) == (220, 40, 40) and quality_color(None) == (150, 150, 150)
