"""`irloc serve`: the server with the viewer handed in (the one place that wires both).

`server.cli.main` parses the options and runs the API; this module adds the viewer
(`web.viewer.Viewer`), since the server itself never imports `web`.

`irloc serve --ros2 --mqtt URL`: the demo as ROS 2 robots (docs/ros2.md). The site runs
its world and radio but not its robots (`--no-sim-robots`); beside it one `irloc agent
--ros2 --sim --name all` process runs every robot of the scenario as a ROS 2 robot appears
(a simulated driver publishing `/<robot>/image_raw`, `camera_info`, `odom`, `/tf`,
`ground_truth`) and its localizer as a ROS 2 agent on those topics, on `ROS_DOMAIN_ID`.
`--ros2-site`: the site server itself publishes every robot's pose and the landmark map on
ROS 2 (`irloc.ros2_site`).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

from live.settings import Settings
from server.cli import main as serve_main
from server.seams import ViewerApp


def make_viewer(settings: Settings) -> ViewerApp | None:
    """The viewer for `settings` (None when `viewer_enabled` is off), on a loopback port."""
    if not settings.viewer_enabled:
        return None
    from web.viewer import Viewer

    return Viewer(host="127.0.0.1", port=settings.viewer_port)


def make_viewer_with_ros2_site(settings: Settings) -> ViewerApp | None:
    """The viewer, with every robot's pose and the map published on ROS 2 beside it."""
    from irloc.ros2_site import SitePublisher, SiteWithRos2

    return SiteWithRos2(make_viewer(settings), SitePublisher())


def _ros2_options(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument("--ros2", action="store_true")
    p.add_argument("--ros2-site", action="store_true")
    p.add_argument("--ros2-camera-rate", type=float, default=10.0)
    p.add_argument("--mqtt")
    p.add_argument("--scenario")
    p.add_argument("--seed", type=int)
    return p.parse_known_args(argv)


def ros2_agents_command(
    mqtt: str, scenario: str | None, seed: int | None, camera_rate: float
) -> list[str]:
    """The `irloc agent` process of the demo's ROS 2 robots."""
    cmd = [
        sys.executable,
        "-m",
        "irloc",
        "agent",
        "--mqtt",
        mqtt,
        "--ros2",
        "--sim",
        "--name",
        "all",
        "--start-known",
        "--camera-rate",
        str(camera_rate),
        "--log-level",
        "warning",
    ]
    if scenario is not None:
        cmd += ["--scenario", scenario]
    if seed is not None:
        cmd += ["--seed", str(seed)]
    return cmd


def _die_with_parent() -> None:
    """In the agents' process before it runs: SIGTERM when `irloc serve` dies (uvicorn
    re-raises the signal that stopped it, so its `finally` does not always run)."""
    import ctypes
    import signal

    ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    ros2, _ = _ros2_options(args)
    viewer = make_viewer_with_ros2_site if ros2.ros2_site else make_viewer
    args = [a for a in args if a != "--ros2-site"]
    if not ros2.ros2:
        return serve_main(args, make_viewer=viewer)
    if not ros2.mqtt:
        print(
            "irloc serve: --ros2 runs the robots as ROS 2 agents of this site: give the site's "
            "broker with --mqtt mqtt://HOST[:PORT]",
            file=sys.stderr,
        )
        return 2
    rest = [a for a in args if a != "--ros2"]
    i = next((k for k, a in enumerate(rest) if a == "--ros2-camera-rate"), None)
    if i is not None:
        del rest[i : i + 2]
    if "--no-sim-robots" not in rest:
        rest.append("--no-sim-robots")
    cmd = ros2_agents_command(ros2.mqtt, ros2.scenario, ros2.seed, ros2.ros2_camera_rate)
    if "IRLOC_MQTT_AGENTS" not in os.environ:  # the site admits the agents it starts itself
        from sim.scenario import load_scenario

        names = [r.name for r in load_scenario(ros2.scenario or "demo").robots]
        os.environ["IRLOC_MQTT_AGENTS"] = json.dumps(names)
    print(f"irloc: ros2      robots on ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}")
    linux = sys.platform.startswith("linux")
    agents = subprocess.Popen(cmd, preexec_fn=_die_with_parent if linux else None)
    try:
        return serve_main(rest, make_viewer=viewer)
    finally:
        agents.terminate()
        try:
            agents.wait(10)
        except subprocess.TimeoutExpired:
            agents.kill()
