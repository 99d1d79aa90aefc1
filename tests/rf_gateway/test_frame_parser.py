from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from rf_gateway import frames as fr
from rf_gateway.frame_parser import StreamParser

ADDR = 0x0013A20040A0007E  # contains 0x13 and 0x7E: escaped in mode 2, 0x7E inside in mode 1


def test_mode1_parser_follows_length_over_0x7e_inside_a_frame() -> None:
    frame = fr.RemoteAtCommand(0x7E, ADDR, "D4", b"\x7e")
    raw = fr.wrap(fr.encode(frame))
    assert raw.count(0x7E) >= 3
    parser = StreamParser()
    assert [fr.decode(d) for d in parser.feed(raw + raw)] == [frame, frame]


def test_garbage_bad_checksum_truncated_and_bad_length_are_counted_and_skipped() -> None:
    good = fr.wrap(fr.encode(fr.AtResponse(9, "NI", 0, b"LM")))
    bad_sum = bytearray(good)
    bad_sum[-1] ^= 0x01
    truncated = good[:5]
    bad_length = bytes((0x7E, 0xFF, 0xFF))
    stream = b"\x00\x55\xaa" + good + bytes(bad_sum) + truncated + good + bad_length + good
    parser = StreamParser()
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
    parser = StreamParser(escaped=True)
    out = parser.feed(good[:9] + good)
    assert len(out) == 1
    assert parser.stats.truncated == 1


def test_expire_drops_a_partial_frame() -> None:
    parser = StreamParser()
    parser.feed(b"\x7e\x00\x05\x88")
    assert parser.pending == 3
    parser.expire()
    assert (parser.pending, parser.stats.truncated) == (0, 1)


@settings(deadline=None)
@given(st.binary(max_size=300), st.booleans())
def test_parser_never_raises_on_random_bytes(noise: bytes, escaped: bool) -> None:
    parser = StreamParser(escaped=escaped)
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
    out = StreamParser().feed(bytes(stream))
    assert out == [frame_data] * 50
