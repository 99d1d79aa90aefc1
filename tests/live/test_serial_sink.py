"""The serial pose line: format, checksum, and the sink thread writing the pose bus."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest

from live.poses import PoseUpdate
from live.serial_sink import SerialSink, nmea_checksum, parse_pose_line, pose_line
from pubsub.bus import Bus


def test_checksum_is_the_nmea_xor() -> None:
    # a classic NMEA sentence and its published checksum
    assert (
        nmea_checksum("GPGGA,092750.000,5321.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,") == "76"
    )


def test_line_round_trip() -> None:
    upd = PoseUpdate("r1", 1_500_000_000, "landmark", 1.2344, -0.5, 0.785398, np.eye(3))
    line = pose_line(upd)
    assert line.startswith("$IRLOC,r1,1500000000,1.234,-0.500,0.7854,landmark*")
    assert line.endswith("\r\n")
    got = parse_pose_line(line)
    np.testing.assert_allclose([got["x"], got["y"], got["theta"]], [1.234, -0.5, 0.7854])
    assert got["mode"] == "landmark" and got["t_ns"] == 1_500_000_000


def test_no_pose_has_empty_fields_and_bad_checksum_is_refused() -> None:
    line = pose_line(PoseUpdate("r2", 7, "identifying"))
    assert line.startswith("$IRLOC,r2,7,,,,identifying*")
    assert parse_pose_line(line)["x"] is None
    with pytest.raises(ValueError, match="checksum"):
        parse_pose_line(line.replace("r2", "r3"))


class _Sink(io.BytesIO):
    def close(self) -> None:  # keep the bytes readable after stop()
        pass


def test_sink_writes_every_pose_of_its_robot() -> None:
    bus: Bus[PoseUpdate] = Bus()
    out = _Sink()
    sink = SerialSink(bus.subscribe(accept=lambda p: p.robot == "r1"), out)
    sink.start()
    for i in range(5):
        bus.publish(PoseUpdate("r1", i, "dead_reckoning", float(i), 0.0, 0.0))
        bus.publish(PoseUpdate("r2", i, "lost"))
    for _ in range(100):
        if sink.lines == 5:
            break
        time.sleep(0.01)
    sink.stop()
    lines = out.getvalue().decode().splitlines()
    assert [parse_pose_line(s)["x"] for s in lines] == [0.0, 1.0, 2.0, 3.0, 4.0]
