"""Keeping the map true (`survey.upkeep`): the demo site's robots patrol on a map with a 3 mm
survey error in which one landmark was moved by 5 cm (a replaced ceiling tile).

Prints when the moved landmark is proposed (simulated time and its views), every other
proposal of kind "moved" over the whole run (false proposals), then accepts every proposal
(moved and refined, as staff would) and patrols again: heading and position error in
landmark mode before and after, against the truth, with the true map as the reference.

    PYTHONPATH=$PWD .venv/bin/python -m bench.bench_map_upkeep [--minutes 10] [--seed 5]

Simulated time on the spot-level camera (`sim.spot_view`: the true, miscalibrated camera's
projections with centroid noise), all LEDs lit, every localizer started from its robot's
true start pose; runs faster than real time (about 6x here).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable

import numpy as np

from localizer.events import LedRequest, LedsChanged, OdometryMeasured, PoseEstimate, SpotsObserved
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from sim.scenario import load_scenario
from sim.virtual_site import VirtualSite
from survey.upkeep import MapUpkeep, UpkeepConfig

NS = 1_000_000_000
STEP_NS = 50_000_000


@dataclasses.dataclass
class Errors:
    """Heading (rad) and position (m) errors of landmark-mode frames."""

    heading: list[float] = dataclasses.field(default_factory=list)
    position: list[float] = dataclasses.field(default_factory=list)
    robot: list[str] = dataclasses.field(default_factory=list)

    def line(self) -> str:
        out = [self._stats(np.ones(len(self.heading), dtype=bool))]
        names = np.array(self.robot)
        for name in sorted(set(self.robot)):
            out.append(f"  {name}: {self._stats(names == name)}")
        return "\n".join(out)

    def _stats(self, keep: np.ndarray) -> str:
        h = np.degrees(np.abs(np.asarray(self.heading)[keep]))
        p = np.asarray(self.position)[keep] * 1000
        return (
            f"heading |err| mean {h.mean():.3f} deg, p95 {np.percentile(h, 95):.3f} deg; "
            f"position mean {p.mean():.1f} mm, p95 {np.percentile(p, 95):.1f} mm "
            f"({len(h)} frames)"
        )


def patrol(
    site: VirtualSite,
    positions: dict[int, np.ndarray],
    seconds: float,
    on_frame: Callable[[str, PoseEstimate, np.ndarray, float], None],
) -> Errors:
    """Localize every robot of `site` on the map `positions` for `seconds` of site time."""
    lm = LandmarkMap(
        np.array(sorted(positions)), np.array([positions[i] for i in sorted(positions)])
    )
    locs: dict[str, Localizer] = {}
    t0 = site._t0_ns or 0
    t_now = site._t_local_ns + t0
    if site._t0_ns is None:
        site.step(t_now)
    for name in site.robot_names:
        loc = Localizer(site.camera(name), lm, site.robot_geometry(name))
        loc.set_initial_pose(*site.true_pose(name), t_now)
        locs[name] = loc
    err = Errors()
    end = t_now + round(seconds * NS)
    requests: dict[str, LedRequest] = {}
    while t_now < end:
        if requests:
            lit = _carry_out(site, requests)
            for loc in locs.values():
                loc.handle(LedsChanged(t_now, lit))
            requests.clear()
        t_now += STEP_NS
        for s in site.step(t_now):
            outs = locs[s.robot].handle(s.event)
            for out in outs:
                if isinstance(out, LedRequest):
                    requests[s.robot] = out
            if isinstance(s.event, OdometryMeasured):
                continue
            truth = site.true_pose_at(s.robot, s.event.t_ns)
            for out in outs:
                if not isinstance(out, PoseEstimate) or truth is None:
                    continue
                if out.mode == "landmark":
                    err.heading.append(math.remainder(out.theta - truth[2], math.tau))
                    err.position.append(math.hypot(out.x - truth[0], out.y - truth[1]))
                    err.robot.append(s.robot)
                assert isinstance(s.event, SpotsObserved)
                on_frame(s.robot, out, s.event.pixels, (t_now - t0) / NS)
    return err


def _carry_out(site: VirtualSite, requests: dict[str, LedRequest]) -> frozenset[int]:
    """The robots' LED requests, at once and all of them (a radio without latency): one that
    lights only some LEDs wins, else every LED but those any robot wants dark."""
    ids = set(site.world.landmarks)
    only = [r for r in requests.values() if not r.all_lit]
    lit = set(only[-1].lit) if only else ids - set().union(*(r.dark for r in requests.values()))
    for lid in ids:
        site.world.set_led(lid, lid in lit)
    return frozenset(lit)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="patrol before accepting")
    ap.add_argument("--after-minutes", type=float, default=3.0, help="patrol after")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--survey-mm", type=float, default=3.0)
    ap.add_argument("--move-mm", type=float, default=50.0)
    ap.add_argument("--landmark", type=int, default=114)
    args = ap.parse_args()
    sc = dataclasses.replace(load_scenario("demo"), survey_sigma_m=args.survey_mm / 1000)
    site = VirtualSite(sc, seed=args.seed, observe="spots")
    moved = site.world.landmarks[args.landmark]
    direction = np.array([0.8, 0.6, 0.0])
    moved.p_true = moved.p_true + direction * args.move_mm / 1000
    surveyed = {lid: lm.p_surveyed.copy() for lid, lm in site.world.landmarks.items()}
    truth = {lid: lm.p_true.copy() for lid, lm in site.world.landmarks.items()}
    upkeep = MapUpkeep(UpkeepConfig(map_sigma_m=args.survey_mm / 1000))
    upkeep.set_map(surveyed)
    first: dict[int, tuple[float, int, float]] = {}
    cameras = {name: site.camera(name) for name in site.robot_names}
    last_check = [0.0]
    wall, cpu = time.perf_counter(), time.process_time()

    def on_frame(robot: str, pose: PoseEstimate, pixels: np.ndarray, t_s: float) -> None:
        upkeep.observe(robot, cameras[robot], pose, pixels)
        if t_s - last_check[0] < 1.0:
            return
        last_check[0] = t_s
        for p in upkeep.proposals():
            if p.kind == "moved" and p.landmark_id not in first:
                first[p.landmark_id] = (t_s, p.views, p.statistic)
                err = np.linalg.norm(np.array(p.proposed) - truth[p.landmark_id]) * 1000
                tag = "the moved one" if p.landmark_id == args.landmark else "FALSE"
                print(
                    f"t={t_s:6.1f} s landmark {p.landmark_id} proposed moved ({tag}): "
                    f"{p.views} views, chi2 {p.statistic:.0f}, shift {p.shift_m * 1000:.1f} mm, "
                    f"sigma {p.sigma_m * 1000:.1f} mm, {err:.1f} mm from the truth",
                    flush=True,
                )

    before = patrol(site, surveyed, args.minutes * 60, on_frame)
    sim_s = args.minutes * 60
    print(
        f"{sim_s:.0f} s simulated in {time.perf_counter() - wall:.0f} s wall, "
        f"{time.process_time() - cpu:.0f} s CPU; "
        f"{upkeep.frames} frames counted"
    )
    false = [lid for lid in first if lid != args.landmark]
    print(
        f"moved landmark {args.landmark}: "
        + (
            f"proposed after {first[args.landmark][0]:.0f} s, {first[args.landmark][1]} views"
            if args.landmark in first
            else "NOT proposed"
        )
        + f"; false 'moved' proposals: {len(false)} {false}"
    )
    props = upkeep.proposals()
    report_map("surveyed map", surveyed, truth)
    refined = dict(surveyed)
    for p in props:
        refined[p.landmark_id] = np.array(p.proposed)
    n_ref = sum(p.kind == "refined" for p in props)
    report_map(f"after accepting {len(props)} proposals ({n_ref} refined)", refined, truth)
    print(f"before (surveyed map): {before.line()}")
    for label, positions in (
        ("after accepting", refined),
        ("true map (reference)", truth),
        ("surveyed map again", surveyed),
    ):
        site2 = VirtualSite(sc, seed=args.seed + 1, observe="spots")
        site2.world.landmarks[args.landmark].p_true = truth[args.landmark].copy()
        e = patrol(site2, positions, args.after_minutes * 60, lambda *a: None)
        print(f"{label}: {e.line()}")


def report_map(label: str, positions: dict[int, np.ndarray], truth: dict[int, np.ndarray]) -> None:
    err = np.array([np.linalg.norm(positions[i][:2] - truth[i][:2]) for i in sorted(truth)])
    ez = np.array([abs(positions[i][2] - truth[i][2]) for i in sorted(truth)])
    print(
        f"{label}: x-y error vs truth median {np.median(err) * 1000:.2f} mm, "
        f"p95 {np.percentile(err, 95) * 1000:.2f} mm, max {err.max() * 1000:.1f} mm; "
        f"z median {np.median(ez) * 1000:.2f} mm"
    )


if __name__ == "__main__":
    main()
