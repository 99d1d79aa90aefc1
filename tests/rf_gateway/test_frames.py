from __future__ import annotations

import random

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rf_gateway import frames as fr

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
    parser = fr.StreamParser(escaped=escaped)
    raw = fr.wrap(fr.encode(frame), escaped=escaped)
    if escaped:
        assert fr.START not in raw[1:]
    got = parser.feed(raw)
    assert [fr.decode(d) for d in got] == [frame]
    assert parser.stats == fr.ParserStats(frames=1)


def test_mode1_parser_follows_length_over_0x7e_inside_a_frame() -> None:
    frame = fr.RemoteAtCommand(0x7E, ADDR, "D4", b"\x7e")
    raw = fr.wrap(fr.encode(frame))
    assert raw.count(0x7E) >= 3
    parser = fr.StreamParser()
    assert [fr.decode(d) for d in parser.feed(raw + raw)] == [frame, frame]


def test_garbage_bad_checksum_truncated_and_bad_length_are_counted_and_skipped() -> None:
    good = fr.wrap(fr.encode(fr.AtResponse(9, "NI", 0, b"LM")))
    bad_sum = bytearray(good)
    bad_sum[-1] ^= 0x01
    truncated = good[:5]
    bad_length = bytes((0x7E, 0xFF, 0xFF))
    stream = b"\x00\x55\xaa" + good + bytes(bad_sum) + truncated + good + bad_length + good
    parser = fr.StreamParser()
    out = parser.feed(stream)
    assert out == [fr.encode(fr.AtResponse(9, "NI", 0, b"LM"))] * 3
    s = parser.stats
    assert (s.frames, s.garbage_bytes, s.bad_checksums, s.truncated, s.bad_lengths) == (
        3,
        3,
        1,
        1,
        1,
    )


def test_escaped_parser_restarts_at_a_delimiter_inside_a_frame() -> None:
    good = fr.wrap(fr.encode(fr.RemoteAtResponse(1, ADDR, 0, "D4", 0)), escaped=True)
    parser = fr.StreamParser(escaped=True)
    out = parser.feed(good[:9] + good)
    assert len(out) == 1
    assert parser.stats.truncated == 1


def test_expire_drops_a_partial_frame() -> None:
    parser = fr.StreamParser()
    parser.feed(b"\x7e\x00\x05\x88")
    assert parser.pending == 3
    parser.expire()
    assert (parser.pending, parser.stats.truncated) == (0, 1)


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


@given(st.binary(max_size=300), st.booleans())
def test_parser_never_raises_on_random_bytes(noise: bytes, escaped: bool) -> None:
    parser = fr.StreamParser(escaped=escaped)
    frame = fr.encode(fr.RemoteAtResponse(1, ADDR, 0, "D4", 0))
    out = parser.feed(noise + b"\x00" * 4 + fr.wrap(frame, escaped=escaped))
    # noise may swallow the frame's start, but whatever comes out passes its checksum
    for data in out:
        assert len(data) >= 1


def test_random_fault_stream_recovers_every_frame_after_faults() -> None:
    rng = random.Random(3)
    frame_data = fr.encode(fr.RemoteAtResponse(1, ADDR, 0, "%V", 0, b"\x0b\xb8"))
    good = fr.wrap(frame_data)
    stream = bytearray()
    for _ in range(50):
        stream += bytes(rng.choice((0x00, 0x11, 0x55)) for _ in range(rng.randrange(4)))
        stream += good
    out = fr.StreamParser().feed(bytes(stream))
    assert out == [frame_data] * 50
