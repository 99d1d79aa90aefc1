"""Topic layout and payloads (fleet/topics.py, fleet/payloads.py, fleet/broker.py)."""

from __future__ import annotations

import numpy as np
import pytest

from fleet.broker import parse_broker_url
from fleet.payloads import (
    AgentStatus,
    LedRequestMessage,
    LedStateMessage,
    PayloadError,
    PoseMessage,
    decode,
)
from fleet.topics import SiteTopics, vda_serial_of, vda_topic
from localizer.events import LedRequest, LedsChanged, NoPose, PoseEstimate


def test_topics_of_a_site_and_what_they_name() -> None:
    t = SiteTopics("hall-1")
    assert t.map == "irloc/v1/hall-1/map" and t.leds == "irloc/v1/hall-1/leds"
    assert t.pose("r1") == "irloc/v1/hall-1/agents/r1/pose"
    assert t.agent_of(t.led_request("r1")) == ("r1", "led_request")
    assert t.agent_of("irloc/v1/other/agents/r1/pose") is None
    assert vda_topic("irloc", "r1", "connection") == "uagv/v2/irloc/r1/connection"
    assert vda_serial_of("uagv/v2/irloc/r7/visualization") == "r7"
    for bad in ("r/1", "r+", "#", ""):
        with pytest.raises(ValueError, match="robot name"):
            t.pose(bad)


def test_broker_urls() -> None:
    assert str(parse_broker_url("mqtt://10.0.0.5")) == "mqtt://10.0.0.5:1883"
    assert parse_broker_url("mqtt://localhost:18830").port == 18830
    for bad, why in (("http://x", "scheme"), ("mqtt://:1883", "no host"), ("mqtt://h:x", "port")):
        with pytest.raises(ValueError, match=why):
            parse_broker_url(bad)


def test_a_pose_round_trips_within_its_rounding_and_stays_small() -> None:
    cov = np.array([[4e-4, 1e-5, 2e-6], [1e-5, 9e-4, -3e-6], [2e-6, -3e-6, 1e-5]])
    est = PoseEstimate(5, 1.234567891, -2.5, 3.0, cov, "landmark", (101, 102))
    wire = PoseMessage.from_estimate(
        7, est, 1_700_000_000_000_000_000, 1_700_000_000_001_000_000
    ).encode()
    assert len(wire) < 200
    back = decode(PoseMessage, "t", wire)
    assert (back.seq, back.mode, back.lm) == (7, "landmark", [101, 102])
    assert back.x == pytest.approx(1.23457, abs=1e-9)
    np.testing.assert_allclose(back.covariance(), cov, rtol=1e-3)


def test_quality_and_reason_travel_with_a_pose_and_a_no_pose() -> None:
    cov = np.diag([4e-4, 9e-4, 1e-5])
    est = PoseEstimate(5, 1.0, 2.0, 0.5, cov, "dead_reckoning", quality=0.61234,
                       deviation_m=0.0712345, reason="landmarks_dark",
                       reason_text="the 2 landmark(s) in view are switched off")  # fmt: skip
    back = decode(PoseMessage, "t", PoseMessage.from_estimate(1, est, 5, 6).encode())
    assert (back.quality, back.deviation_m, back.reason) == (0.612, 0.07123, "landmarks_dark")
    assert back.reason_text == est.reason_text
    fixed = PoseEstimate(5, 1.0, 2.0, 0.5, cov, "landmark", quality=1.0, deviation_m=0.01)
    wire = PoseMessage.from_estimate(2, fixed, 5, 6).encode()
    assert b"reason" not in wire
    none = NoPose(5, "identifying", reason="waiting_for_radio", reason_text="waiting")
    back = decode(PoseMessage, "t", PoseMessage.from_no_pose(3, none, 5, 6).encode())
    assert (back.x, back.quality, back.reason) == (None, 0.0, "waiting_for_radio")
    with pytest.raises(PayloadError, match="reason"):
        decode(PoseMessage, "t", b'{"seq":1,"t_ns":1,"wall_ns":1,"mode":"lost","reason":"x"}')


def test_led_states_and_requests_round_trip() -> None:
    ev = LedsChanged(3, frozenset({5, 1}), False, frozenset({7}))
    msg = decode(LedStateMessage, "t", LedStateMessage.from_event(4, ev, 99).encode())
    back = msg.event(11)
    assert (back.t_ns, back.lit, back.all_lit, back.changing) == (11, {1, 5}, False, {7})
    req = LedRequest(all_lit=True, dark=frozenset({3}))
    assert (
        decode(LedRequestMessage, "t", LedRequestMessage.from_request(req).encode()).request()
        == req
    )
    with pytest.raises(ValueError, match="dark"):
        LedRequestMessage(dark=[3]).request()


def test_bad_payloads_name_the_topic_and_field() -> None:
    with pytest.raises(PayloadError, match=r"irloc/v1/s/agents/r1/pose: mode"):
        decode(
            PoseMessage, "irloc/v1/s/agents/r1/pose", b'{"seq":1,"t_ns":1,"wall_ns":1,"mode":"x"}'
        )
    with pytest.raises(PayloadError, match="wheel_base"):
        decode(
            AgentStatus,
            "s",
            b'{"source":"sim","camera":{},"wheel_base":-1,"mode":"lost","max_speed":1}',
        )
    with pytest.raises(PayloadError, match="message"):
        decode(PoseMessage, "p", b"not json")


def test_a_confident_frame_carries_its_spots_for_map_upkeep() -> None:
    cov = np.diag([1e-4, 1e-4, 1e-5])
    est = PoseEstimate(5, 1.0, 2.0, 0.1, cov, "landmark", (101, 102), (101, 102, 103))
    spots = np.array([[100.123456, 200.5], [320.0, 240.25]])
    wire = PoseMessage.from_estimate(7, est, 1, 2, spots).encode()
    back = decode(PoseMessage, "t", wire)
    assert back.spots == [(100.12, 200.5), (320.0, 240.25)]
    assert back.ex == [101, 102, 103]
    plain = decode(PoseMessage, "t", PoseMessage.from_estimate(7, est, 1, 2).encode())
    assert plain.spots is None and plain.ex is None  # not sent with every pose
    with pytest.raises(PayloadError, match="spots"):
        decode(PoseMessage, "agents/r1/pose", wire.replace(b"320.0", b"1e999"))
