"""XBeeTransport through digi-xbee and pyserial against the emulated coordinator (no mocks)."""

from __future__ import annotations

import asyncio
import dataclasses
import itertools
import os
import time
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path

import pytest
import serial

from localizer.events import LedsChanged
from rf_gateway import frames as fr
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.config import GatewayConfig
from rf_gateway.emulator import EmulatedRemote, FaultConfig, XBeeEmulator
from rf_gateway.errors import RadioTimeout, RemoteCommandError, TransportUnavailable
from rf_gateway.events import TransportStateChanged
from rf_gateway.frame_parser import StreamParser
from rf_gateway.gateway import Gateway
from rf_gateway.transport import DiscoveredRadio, TransportState
from rf_gateway.xbee_transport import XBeeTransport, XBeeTransportConfig

ADDR = {i: f"0013A20040A000{i:02X}" for i in (1, 2, 3, 4)}
CONFIG = XBeeTransportConfig(command_timeout_s=0.4, reopen_initial_s=0.05, reopen_max_s=0.2)
GW_CONFIG = GatewayConfig(
    max_tries=8,
    retry_backoff_s=0.01,
    light_all_on_start=False,
    battery=BatteryMonitorConfig(interval_s=None),
)


def remotes() -> list[EmulatedRemote]:
    return [
        EmulatedRemote(ADDR[1], "LM-1", 3100),
        EmulatedRemote(ADDR[2], "LM-2", 2950),
        EmulatedRemote(ADDR[3], "LM-3", reachable=False),
        EmulatedRemote(ADDR[4], "LM-4", silent=True),
    ]


PIPELINED = dataclasses.replace(CONFIG, pipelined=True)


@dataclasses.dataclass
class Link:
    """An emulated coordinator and the transport settings to reach it with."""

    emu: XBeeEmulator
    config: XBeeTransportConfig


@pytest.fixture(
    params=[(False, CONFIG), (True, CONFIG), (False, PIPELINED)],
    ids=["api1", "api2-escaped", "api1-pipelined"],
)
def link(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Link]:
    escaped, config = request.param
    emu = XBeeEmulator(tmp_path / "ttyXBEE", remotes(), escaped=escaped)
    emu.start()
    yield Link(emu, config)
    emu.stop()


async def until(predicate: Callable[[], bool], timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("condition not reached")
        await asyncio.sleep(0.02)


def with_transport(link: Link, body: Callable[[XBeeTransport], Awaitable[None]]) -> None:
    async def main() -> None:
        transport = XBeeTransport(str(link.emu.port), 115200, pin="D4", config=link.config)
        await transport.open()
        try:
            await body(transport)
        finally:
            await transport.close()

    asyncio.run(main())


def test_pin_supply_and_discovery_through_digi_xbee(link: Link) -> None:
    async def body(t: XBeeTransport) -> None:
        assert t.state == "open"
        await t.set_pin(ADDR[1].lower(), True)
        await t.set_pin(ADDR[2], True)
        await t.set_pin(ADDR[2], False)
        assert await t.read_supply_mv(ADDR[1]) == 3100
        assert await t.read_supply_mv(ADDR[2]) == 2950
        assert await t.discover() == [
            DiscoveredRadio(ADDR[1], "LM-1"),
            DiscoveredRadio(ADDR[2], "LM-2"),
        ]

    with_transport(link, body)
    assert link.emu.remote(ADDR[1]).applied == [("D4", 5)]
    assert link.emu.remote(ADDR[2]).applied == [("D4", 5), ("D4", 4)]
    assert link.emu.counts["LocalAtCommand"] >= 8  # AP HV VR SH SL NI MY CE on open, ND...


def test_unreachable_and_silent_remotes(link: Link) -> None:
    async def body(t: XBeeTransport) -> None:
        with pytest.raises(RemoteCommandError) as failure:
            await t.set_pin(ADDR[3], True)
        assert (failure.value.status, failure.value.retryable) == (4, True)
        with pytest.raises(RadioTimeout, match=ADDR[4]):
            await t.read_supply_mv(ADDR[4])
        with pytest.raises(ValueError, match="16 hex digits"):
            await t.set_pin("12345", True)
        await t.set_pin(ADDR[1], True)  # the link is still fine

    with_transport(link, body)
    assert link.emu.counts["tx_failures"] == 1
    assert link.emu.counts["silent"] == 1


def test_bad_pin_name_is_rejected() -> None:
    with pytest.raises(ValueError, match="LED pin 'A4'"):
        XBeeTransport("/dev/null", pin="A4")


def run_gateway_sequence(
    link: Link, sequence: list[list[int]], linger_s: float = 0.0
) -> tuple[Gateway, list[LedsChanged]]:
    async def main() -> tuple[Gateway, list[LedsChanged]]:
        transport = XBeeTransport(str(link.emu.port), config=link.config)
        gw = Gateway(transport, {1: ADDR[1], 2: ADDR[2]}, GW_CONFIG)
        await gw.start()
        sub = gw.subscribe()
        try:
            for lit in sequence:
                await gw.set_leds(lit)
            await asyncio.sleep(linger_s)
        finally:
            await gw.close()
        events = []
        while (ev := sub.get_nowait()) is not None:
            if not ev.changing:  # the confirmed states, not the announcements
                events.append(ev)
        return gw, events

    return asyncio.run(main())


SEQUENCE = [[1], [2], [1, 2], [], [2], [1]]
FINAL_PINS = {ADDR[1]: {"D4": 5}, ADDR[2]: {"D4": 4}}


@pytest.mark.parametrize(
    "faults, counter",
    [
        pytest.param(FaultConfig(drop=0.3, seed=1), "dropped", marks=pytest.mark.slow),
        (FaultConfig(corrupt=0.3, seed=2), "corrupted"),
        (FaultConfig(duplicate=1.0, seed=3), "duplicated"),
        (FaultConfig(delay_s=0.03, jitter_s=0.02, seed=4), None),
        (FaultConfig(garbage=1.0, seed=5), "garbage_sent"),
        (FaultConfig(truncated=0.3, seed=6), "truncated_sent"),
        (FaultConfig(unknown=1.0, seed=7), "unknown_sent"),
    ],
    ids=["drop", "corrupt", "duplicate", "delay", "garbage", "truncated", "unknown"],
)
def test_gateway_over_faulty_link_applies_every_change_once(
    link: Link, faults: FaultConfig, counter: str | None
) -> None:
    link.emu.faults = faults
    link.emu._rng.seed(faults.seed)
    gw, events = run_gateway_sequence(link, SEQUENCE)
    assert {a: link.emu.remote(a).pins for a in FINAL_PINS} == FINAL_PINS
    assert [e.lit if not e.all_lit else frozenset({1, 2}) for e in events] == [
        frozenset(s) for s in SEQUENCE
    ]
    assert all(b.t_ns >= a.t_ns for a, b in itertools.pairwise(events))
    if counter is not None:
        assert link.emu.counts[counter] > 0
    stats = gw.transport.link_stats  # type: ignore[attr-defined]
    assert stats.frames_received >= 10  # one reply per LED change of SEQUENCE
    if counter == "corrupted":
        assert stats.invalid_frames >= link.emu.counts["corrupted"]
    if counter == "unknown_sent":
        assert stats.unknown_frames == link.emu.counts["unknown_sent"]
    if counter in ("dropped", "corrupted"):
        # each lost reply cost one timeout and one retry, nothing else
        assert gw.stats.retries >= link.emu.counts[counter]
    assert gw.unreachable == frozenset()


def test_late_reply_crossing_a_retry_is_not_taken_for_a_newer_command(
    link: Link,
) -> None:
    remote = link.emu.remote(ADDR[1])
    remote.late_replies = 1
    remote.late_delay_s = 0.7  # longer than the 0.4 s command timeout
    gw, events = run_gateway_sequence(link, [[1], [], [1]], linger_s=0.6)
    assert gw.stats.retries == 1
    # the first command was applied when it arrived and again by the retry (idempotent);
    # the late reply to it, received while the next command waited, confirmed nothing
    assert remote.applied == [("D4", 5), ("D4", 5), ("D4", 4), ("D4", 5)]
    assert [e.lit for e in events] == [frozenset({1}), frozenset(), frozenset({1})]
    if link.config.pipelined:
        assert gw.transport.replies.late_replies == 1  # type: ignore[attr-defined]


@pytest.mark.parametrize("config", [CONFIG, PIPELINED], ids=["sync", "pipelined"])
def test_pipelined_commands_share_the_air(tmp_path: Path, config: XBeeTransportConfig) -> None:
    many = [EmulatedRemote(f"0013A20040C000{i:02X}", f"LM{i}", delay_s=0.03) for i in range(8)]

    async def main() -> None:
        transport = XBeeTransport(str(emu.port), config=config)
        gw = Gateway(transport, {i: r.address for i, r in enumerate(many)}, GW_CONFIG)
        await gw.start()
        await gw.set_leds(range(8))
        await gw.close()

    with XBeeEmulator(tmp_path / "ttyMANY", many) as emu:
        asyncio.run(main())
    assert all(r.pins == {"D4": 5} for r in many)
    # replies still pending when the next request arrived: none when serial, up to 3 of the
    # gateway's 4 in flight when pipelined
    expected = range(1, 4) if config.pipelined else range(0, 1)
    assert emu.counts["max_overlap"] in expected


def test_our_parser_counts_and_skips_garbage_sent_over_the_serial_line(
    link: Link,
) -> None:
    good = fr.wrap(fr.encode(fr.LocalAtCommand(7, "NI")), escaped=link.emu.escaped)
    bad = bytearray(good)
    bad[-1] ^= 0x01
    unknown = fr.wrap(fr.encode(fr.UnknownFrame(0x3F, b"\x00")), escaped=link.emu.escaped)
    with serial.Serial(str(link.emu.port), 9600, timeout=1.0) as port:
        port.write(b"\x00\x41\x42" + bytes(bad) + good[:4] + unknown + good)
        header = port.read(3)
        assert header[0] == fr.START
        reply = StreamParser(escaped=link.emu.escaped).feed(header + port.read(64))
    assert fr.decode(reply[0]) == fr.AtResponse(7, "NI", 0, b"COORDINATOR")
    stats = link.emu.parser.stats
    assert (stats.garbage_bytes, stats.bad_checksums + stats.truncated, stats.frames) == (3, 2, 2)
    assert link.emu.counts["unknown_frames"] == 1


def test_pulled_cable_is_reopened_and_reported(tmp_path: Path) -> None:
    async def main() -> list[TransportState]:
        with XBeeEmulator(tmp_path / "ttyXBEE", remotes()) as emu:
            transport = XBeeTransport(str(emu.port), config=CONFIG)
            gw = Gateway(transport, {1: ADDR[1]}, GW_CONFIG)
            events = gw.subscribe_events()
            await gw.start()
            await gw.led(1, True)
            emu.pull_cable()
            await until(lambda: transport.state == "reopening")
            with pytest.raises(TransportUnavailable):
                await transport.set_pin(ADDR[1], False)
            emu.plug_in()
            await until(lambda: transport.state == "open")
            await gw.led(1, False)
            assert emu.remote(ADDR[1]).pins == {"D4": 4}
            assert transport.reopen_count == 1
            await gw.close()
        states = []
        while (ev := events.get_nowait()) is not None:
            assert isinstance(ev, TransportStateChanged)
            states.append(ev.state)
        return states

    assert asyncio.run(main()) == ["opening", "open", "reopening", "open", "closed"]


def test_missing_port_at_start_keeps_trying_until_it_appears(tmp_path: Path) -> None:
    async def main() -> None:
        port = tmp_path / "ttyLATE"
        transport = XBeeTransport(str(port), config=CONFIG)
        with pytest.raises(TransportUnavailable, match="cannot open"):
            await transport.open()
        assert transport.state == "reopening"
        with XBeeEmulator(port, remotes()):
            await until(lambda: transport.state == "open")
            assert await transport.read_supply_mv(ADDR[1]) == 3100
            await transport.close()
        assert not os.path.exists(port)

    asyncio.run(main())


def test_transmit_requests_get_a_transmit_status(link: Link) -> None:
    esc = link.emu.escaped
    requests = [
        fr.TransmitRequest(11, int(ADDR[1], 16), b"on"),
        fr.TransmitRequest(12, int(ADDR[3], 16), b"on"),
    ]
    with serial.Serial(str(link.emu.port), 9600, timeout=0.5) as port:
        port.write(b"".join(fr.wrap(fr.encode(r), escaped=esc) for r in requests))
        parser = StreamParser(escaped=esc)
        got: list[fr.ApiFrame] = []
        while len(got) < 2:
            chunk = port.read(32)
            assert chunk, "no transmit status"
            got += [fr.decode(d) for d in parser.feed(chunk)]
    statuses = sorted(
        (f.frame_id, f.delivery_status) for f in got if isinstance(f, fr.TransmitStatus)
    )
    assert statuses == [(11, 0x00), (12, 0x21)]


def test_close_stops_reopening(tmp_path: Path) -> None:
    async def main() -> None:
        port = tmp_path / "ttyNEVER"
        transport = XBeeTransport(str(port), config=CONFIG)
        with pytest.raises(TransportUnavailable):
            await transport.open()
        await transport.close()
        with XBeeEmulator(port, remotes()) as emu:
            await asyncio.sleep(0.5)  # several reopen periods
            assert transport.state == "closed"
            assert emu.counts["LocalAtCommand"] == 0

    asyncio.run(main())


def test_a_lost_reply_while_opening_is_retried_at_once(tmp_path: Path) -> None:
    async def main() -> tuple[list[TransportState], float, int]:
        with XBeeEmulator(tmp_path / "ttyNOISY", remotes()) as emu:
            emu.drop_local_replies = 1  # digi-xbee's first local AT command goes unanswered
            transport = XBeeTransport(str(emu.port), config=CONFIG)
            states: list[TransportState] = []
            transport.on_state_change(states.append)
            t0 = time.monotonic()
            await transport.open()  # no TransportUnavailable: the open was retried
            elapsed = time.monotonic() - t0
            assert await transport.read_supply_mv(ADDR[1]) == 3100
            await transport.close()
            return states, elapsed, emu.counts["dropped_local"]

    states, elapsed, dropped = asyncio.run(main())
    assert dropped == 1
    assert states == ["opening", "open", "closed"]  # never "reopening"
    # digi-xbee itself probes AT command mode (guard times) after the lost reply: ~4 s of it
    assert elapsed < 10.0, elapsed


def test_a_broadcast_awake_time_reaches_every_reachable_remote(tmp_path: Path) -> None:
    """`ST` to the broadcast address with frame id 0: every reachable landmark applies it
    (30 s = 0x7530 ms), nothing answers, and the link carries on."""
    emu = XBeeEmulator(tmp_path / "ttyXBEE", remotes())
    emu.start()
    try:

        async def body(t: XBeeTransport) -> None:
            await t.broadcast_awake_time(30.0)
            await until(lambda: emu.counts["broadcasts"] == 1)
            await asyncio.sleep(0.05)
            assert t.replies.late_replies == 0  # no answer came to the broadcast
            await t.set_pin(ADDR[1], True)
            with pytest.raises(ValueError, match="ST"):
                await t.broadcast_awake_time(100.0)

        with_transport(Link(emu, CONFIG), body)
        assert emu.remote(ADDR[1]).applied == [("ST", 30000), ("D4", 5)]
        assert emu.remote(ADDR[2]).applied == [("ST", 30000)]
        assert emu.remote(ADDR[3]).applied == [] and emu.remote(ADDR[4]).applied == []
    finally:
        emu.stop()
