from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rf_gateway import frames as fr
from rf_gateway.frame_parser import ParserStats, StreamParser

ADDR = 0x0013A20040A0007E  # contains 0x13 and 0x7E: escaped in mode 2, 0x7E inside in mode 1


def test_checksum_matches_digi_example() -> None:
    # Digi's example: AT command "NI", frame id 1 -> 7E 00 04 08 01 4E 49 5F
    data = fr.encode(fr.LocalAtCommand(1, "NI"))
    assert fr.wrap(data) == bytes.fromhex("7E00040801 4E495F".replace(" ", ""))


def test_escaping_replaces_the_four_special_bytes() -> None:
    assert fr.escape(bytes((0x7E, 0x7D, 0x11, 0x13, 0x41))) == bytes.fromhex("7D5E7D5D7D317D3341")


FRAMES: list[fr.ApiFrame] = [
    fr.LocalAtCommand(1, "AP"),
    fr.LocalAtCommand(2, "NT", b"\x20", queued=True),
    fr.AtResponse(3, "SH", 0, b"\x00\x13\xa2\x00"),
    fr.RemoteAtCommand(0x7E, ADDR, "D4", b"\x05"),
    fr.RemoteAtResponse(5, ADDR, 0x1234, "%V", 0, b"\x0b\xb8"),
    fr.TransmitRequest(6, ADDR, b"hello"),
    fr.TransmitStatus(7, 0x1234, 2, 0x21, 0),
    fr.UnknownFrame(0x3F, b"\x01\x02"),
]


@pytest.mark.parametrize("frame", FRAMES, ids=lambda f: type(f).__name__)
@pytest.mark.parametrize("escaped", [False, True])
def test_every_frame_round_trips_through_the_parser(frame: fr.ApiFrame, escaped: bool) -> None:
    parser = StreamParser(escaped=escaped)
    raw = fr.wrap(fr.encode(frame), escaped=escaped)
    if escaped:
        assert fr.START not in raw[1:]
    got = parser.feed(raw)
    assert [fr.decode(d) for d in got] == [frame]
    assert parser.stats == ParserStats(frames=1)


def test_unknown_and_short_frames_decode_as_unknown() -> None:
    assert fr.decode(b"\x3f\x01") == fr.UnknownFrame(0x3F, b"\x01")
    assert fr.decode(b"\x97\x01\x02") == fr.UnknownFrame(0x97, b"\x01\x02")
    with pytest.raises(ValueError, match="empty"):
        fr.decode(b"")


def test_node_info_round_trip_and_short_payload() -> None:
    node = fr.NodeInfo(0x1A2B, ADDR, "LM-17", 0, 2)
    assert fr.decode_node_info(fr.encode_node_info(node)) == node
    with pytest.raises(ValueError, match="too short"):
        fr.decode_node_info(b"\x00\x01\x02")


def test_bad_command_and_length_raise() -> None:
    with pytest.raises(ValueError, match="two ASCII"):
        fr.encode(fr.LocalAtCommand(1, "NDX"))
    with pytest.raises(ValueError, match="length"):
        fr.wrap(b"")


@settings(deadline=None)
@given(
    st.integers(0, 255),
    st.integers(0, 2**64 - 1),
    st.integers(0, 0xFFFF),
    st.sampled_from(["D4", "%V", "NI", "P2"]),
    st.integers(0, 255),
    st.binary(max_size=40),
    st.booleans(),
)
def test_remote_response_round_trips_for_any_field_values(
    frame_id: int, a64: int, a16: int, cmd: str, status: int, data: bytes, escaped: bool
) -> None:
    frame = fr.RemoteAtResponse(frame_id, a64, a16, cmd, status, data)
    parser = StreamParser(escaped=escaped)
    assert [fr.decode(d) for d in parser.feed(fr.wrap(fr.encode(frame), escaped=escaped))] == [
        frame
    ]
