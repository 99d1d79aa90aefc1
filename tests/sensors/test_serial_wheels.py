"""Wheel speeds over a serial line: format, checksum, and the source on a real pty."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from live.robots import RobotRunner
from localizer.events import Mode, OdometryMeasured
from localizer.robot import RobotGeometry
from sensors.line_framing import nmea_checksum
from sensors.serial_wheels import SerialWheelSource, parse_wheel_line, wheel_line
from tests.server.conftest import start_api


class _Recorder:
    """A stand-in localizer keeping the events it is fed (what the source delivers)."""

    mode: Mode = "identifying"

    def __init__(self) -> None:
        self.events: list[Any] = []

    def handle(self, event: Any) -> list[Any]:
        self.events.append(event)
        return []

    def set_map(self, landmark_map: Any) -> None:
        pass


def _wait(cond: Callable[[], bool], timeout_s: float = 10.0) -> None:
    t_end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > t_end:
            raise AssertionError("condition not reached")
        time.sleep(0.01)


def test_line_round_trip_and_documented_example() -> None:
    line = wheel_line(0.2, -0.215, 1_500_000_000)
    body = "IRODO,1500000000,0.2000,-0.2150"
    assert line == f"${body}*{nmea_checksum(body)}\r\n"
    assert parse_wheel_line(line) == (1_500_000_000, 0.2, -0.215)
    assert parse_wheel_line("$IRODO,,0.200,0.215*77") == (None, 0.2, 0.215)


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("$IRODO,,0.200,0.215*1C", "checksum 1C != 77"),
        ("IRODO,,0.2,0.2", "expected"),
        ("$" + "IRODO,,0.2" + "*" + nmea_checksum("IRODO,,0.2"), "4 fields"),
        ("$" + "IRODO,x,0.2,0.2" + "*" + nmea_checksum("IRODO,x,0.2,0.2"), "integer"),
        ("$" + "IRODO,,nan,0.2" + "*" + nmea_checksum("IRODO,,nan,0.2"), "v_left = nan"),
        ("$" + "IRODO,,0.2,25" + "*" + nmea_checksum("IRODO,,0.2,25"), "v_right = 25.0"),
    ],
)
def test_bad_lines_are_refused_naming_the_problem(line: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        parse_wheel_line(line)


def _pty(link: Path) -> int:
    """A new pseudo-terminal behind the stable name `link`; returns its master fd."""
    master, slave = os.openpty()
    tmp = link.with_suffix(".new")
    tmp.symlink_to(os.ttyname(slave))
    os.replace(tmp, link)
    os.close(slave)  # the source opens the slave by name, as it would a USB adapter
    return master


def test_source_feeds_a_robot_skips_bad_lines_and_reconnects(tmp_path: Path) -> None:
    link = tmp_path / "robot-wheels"
    rec = _Recorder()
    runner = RobotRunner(
        "r1",
        None,  # type: ignore[arg-type]  # no camera: wheel speeds only
        RobotGeometry(0.4),
        rec,
        publish=lambda _: None,
        request_leds=lambda *_: None,
    )
    master = _pty(link)
    source = SerialWheelSource("r1", str(link), 115200, lambda: 42, retry_s=0.05)
    source.start(lambda _robot, event: runner.handle(event))
    try:
        _wait(lambda: source.connected)
        os.write(master, wheel_line(0.1, 0.12, 1000).encode())
        os.write(master, b"$IRODO,,0.3,0.3*00\r\n")  # wrong checksum
        os.write(master, b"\xff\xfe garbage\r\n")  # not ASCII
        os.write(master, wheel_line(0.2, 0.25).encode()[:9])  # a line in two pieces
        time.sleep(0.05)
        os.write(master, wheel_line(0.2, 0.25).encode()[9:])
        _wait(lambda: source.lines == 2 and source.bad_lines == 2)
        os.close(master)  # the adapter is unplugged
        _wait(lambda: not source.connected)
        master = _pty(link)  # ... and plugged in again
        _wait(lambda: source.connects == 2 and source.connected)
        os.write(master, wheel_line(-0.5, 0.5, 3000).encode())
        _wait(lambda: source.lines == 3)
    finally:
        source.stop()
        os.close(master)
    odo = [e for e in rec.events if isinstance(e, OdometryMeasured)]
    assert [(e.t_ns, e.v_left, e.v_right) for e in odo] == [
        (1000, 0.1, 0.12),
        (42, 0.2, 0.25),
        (3000, -0.5, 0.5),
    ]


@pytest.mark.slow
def test_robot_configured_with_a_wheel_port_reads_it(tmp_path: Path) -> None:
    link = tmp_path / "wheels"
    master = _pty(link)
    try:
        for api in start_api(tmp_path / "site", scenario="paper_testbed"):
            sim_name = api.services.virtual_site.robot_names[0]
            conf = api.client.get(f"/api/v1/robots/{sim_name}/config", headers=api.h("viewer"))
            body = {**conf.json(), "source": "camera", "device": None}
            body |= {"wheel_port": str(link), "wheel_baud": 57600}
            r = api.client.put("/api/v1/robots/cam1/config", json=body, headers=api.h("admin"))
            assert r.status_code == 200, r.text
            assert (r.json()["wheel_port"], r.json()["wheel_baud"]) == (str(link), 57600)
            source = api.services.runner.wheels["cam1"]
            _wait(lambda s=source: s.connected)  # type: ignore[misc]
            os.write(master, wheel_line(0.3, 0.31).encode() + b"$IRODO,,1,1*00\r\n")
            _wait(lambda s=source: s.lines == 1 and s.bad_lines == 1)  # type: ignore[misc]
            text = api.client.get("/api/v1/metrics", headers=api.h("viewer")).text
            assert 'irloc_wheel_lines_total{robot="cam1"} 1.0' in text
            assert 'irloc_wheel_bad_lines_total{robot="cam1"} 1.0' in text
        assert source.connected is False  # stopped with the site
    finally:
        os.close(master)
