"""Doubted landmarks on a fresh virtual demo site with a correct map (survey error 4 mm):
three robots patrol from the start (identifying with darken probes, first fixes, hand-offs,
landmarks entering and leaving the edge of their views), and no landmark is ever doubted."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from commissioning.doubt import DoubtConfig
from tests.web.conftest import running_site
from web.adapter import SiteAdapter

pytestmark = pytest.mark.slow

JUDGED = 15  # landmarks judged (`DoubtConfig.min_chances` chances each) before it stops
DEADLINE_S = 90.0  # ... at the latest (about 25 s on the demo, patrolling from the start)


def test_no_landmark_is_doubted_on_a_correct_map_from_the_start(tmp_path: Path) -> None:
    with running_site(tmp_path, seed=5) as (app, _port):
        services = app.state.services
        site = SiteAdapter(services)
        min_chances = DoubtConfig().min_chances
        try:
            start = time.monotonic()
            doubted: dict[int, tuple[float, str]] = {}
            samples = 0
            records = judged = []
            # every 0.5 s from the start, until the rule has judged enough landmarks (a
            # landmark can only be doubted once it had `min_chances` chances)
            while time.monotonic() - start < DEADLINE_S:
                time.sleep(max(0.0, start + 0.5 * (samples + 1) - time.monotonic()))
                samples += 1
                when = round(time.monotonic() - start, 1)
                for c in site.to_identify():
                    doubted.setdefault(c.landmark_id, (when, c.reason))
                for lm in site.landmarks():
                    if lm.doubted:
                        doubted.setdefault(lm.id, (when, "doubted in landmarks()"))
                if samples % 4:  # counted every 2 s
                    continue
                records = [site.doubt(lm.id) for lm in services.map.list()]
                judged = [d for d in records if d.chances >= min_chances]
                if len(judged) >= JUDGED:
                    break
            elapsed = time.monotonic() - start
            assert doubted == {}
            # every 0.5 s or so (a busy machine stretches the period)
            assert samples >= 1.5 * elapsed, (samples, elapsed)
            # the rule was exercised: the landmarks were judged, and used in their chances
            assert len(judged) >= JUDGED, records
            assert sum(d.used for d in judged) >= 0.99 * sum(d.chances for d in judged)
        finally:
            site.close()
