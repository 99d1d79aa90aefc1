"""A real robot's agent (agent/hardware.py): an image sequence as its camera and a
pseudo-terminal as its wheel-speed port feed the localizer, which starts identifying near
where the operator says the robot is (the LED probes themselves need a live site: the
recorded frames cannot answer them; tests/agent/test_fleet_live.py has that)."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from agent.cli import main
from agent.core import AgentConfig, AgentCore
from agent.hardware import HardwareSource
from agent.sim_source import SimRobotSource
from agent.timebase import TimeBase
from fleet.payloads import (
    CommandMessage,
    LedRequestMessage,
    LedStateMessage,
    MapMessage,
    PoseMessage,
)
from fleet.serial_lines import wheel_line
from localizer.geometry import T_world_body_from_pose
from sim.robot import FramePose
from sim.scenario import load_scenario

POSE = (1.8, 1.8, 0.3)


def test_camera_and_wheels_feed_the_localizer_which_probes_near_the_hint(tmp_path: Path) -> None:
    sim = SimRobotSource(load_scenario("demo"), "r1")
    frames = tmp_path / "frames"
    frames.mkdir()
    T = T_world_body_from_pose(*POSE)
    for i in range(40):  # the robot standing still under the lit ceiling
        image = sim._frame(FramePose(i, T, POSE), i)
        cv2.imwrite(str(frames / f"{i:04d}.png"), image.image)  # type: ignore[union-attr]
    master, slave = os.openpty()
    port = os.ttyname(slave)
    source = HardwareSource(
        sim.camera, sim.geometry, device=str(frames / "%04d.png"), wheels=port,
        file_rate_hz=60.0, retry_s=0.05,
    )  # fmt: skip
    core = AgentCore(AgentConfig("hw", source="camera"), source, TimeBase())
    core.on_map(MapMessage(map_id="demo", landmarks=sim.world.landmark_records()))  # type: ignore[arg-type]
    core.on_leds(LedStateMessage(seq=0, t_ns=core.time.site_now_ns(), all_lit=True))
    stop = threading.Event()

    def robot_controller() -> None:
        sent_bad = False
        while not stop.is_set():
            os.write(master, wheel_line(0.0, 0.0).encode())
            if source.lines >= 3 and not sent_bad:  # the port is read: one bad checksum
                os.write(master, b"$IRODO,,0.1,0.1*00\r\n")
                sent_bad = True
            time.sleep(0.02)

    writer = threading.Thread(target=robot_controller, daemon=True)
    # The hint is taken before the camera runs: a frame stamped before the command would be
    # identified without it (on a loaded machine the reader can get ahead of the first tick).
    core.on_command(CommandMessage(command="relocalize", near=(1.75, 1.9, 0.25)))
    outs = core.tick(time.monotonic_ns())
    source.start()
    writer.start()
    try:
        t_end = time.monotonic() + 10
        while time.monotonic() < t_end and source.frames < 40:
            outs += core.tick(time.monotonic_ns())
            time.sleep(0.01)
        time.sleep(0.1)
        outs += core.tick(time.monotonic_ns() + 10**9)
    finally:
        stop.set()
        source.stop()
        os.close(master)
        os.close(slave)
    assert source.frames == 40 and source.lines >= 10 and source.bad_lines == 1
    assert core.frames == 40 and core.errors == 0 and core.mode == "identifying"
    poses = [PoseMessage.model_validate_json(o.payload) for o in outs if o.kind == "pose"]
    assert len(poses) >= 3 and all(p.mode == "identifying" for p in poses)
    np.testing.assert_allclose([poses[-1].x, poses[-1].y], (1.75, 1.9), atol=0.1)
    # its first probe darkens a landmark near the hint
    probes = [
        LedRequestMessage.model_validate_json(o.payload) for o in outs if o.kind == "led_request"
    ]
    assert probes and probes[0].all_lit and len(probes[0].dark) == 1
    lm = sim.world.landmarks[probes[0].dark[0]].p_surveyed
    assert np.hypot(lm[0] - 1.75, lm[1] - 1.9) < 1.5


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--wheels", "/dev/null"], "--sensor"),
        ([], "--camera DEV"),
        (["--camera", "0", "--sensor", "/nonexistent.yaml", "--wheel-base", "0.4"], "nonexistent"),
    ],
)
def test_a_real_robot_agent_names_what_is_missing(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--mqtt", "mqtt://127.0.0.1:1", "--name", "r1", *args]) == 2
    assert message in capsys.readouterr().err
