"""The XBee transport: a Digi XBee coordinator on a serial port, driven by digi-xbee.

Every digi-xbee call runs on one worker thread (concurrent calls on one `XBeeDevice` gave
spurious timeouts), bridged to asyncio with `run_in_executor`. A port that disappears (USB
cable pulled) is noticed by a health check (the port path is gone) or by a failed write; the
transport then closes the device and reopens it with exponential backoff in the background,
reporting its state ("open" -> "reopening" -> "open") to the listeners.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, TypeVar

from digi.xbee.devices import RemoteXBeeDevice, XBeeDevice
from digi.xbee.exception import (
    ATCommandException,
    InvalidOperatingModeException,
    TimeoutException,
)
from digi.xbee.models.address import XBee16BitAddress, XBee64BitAddress
from digi.xbee.models.options import RemoteATCmdOptions
from digi.xbee.packets.common import RemoteATCommandPacket

from rf_gateway.errors import RadioTimeout, RemoteCommandError, TransportUnavailable
from rf_gateway.transport import DEFAULT_BAUD, DiscoveredRadio, StateReporter, normalize_address
from rf_gateway.xbee_link_stats import LinkStats
from rf_gateway.xbee_pipeline import RemoteReply, ReplyRouter

log = logging.getLogger(__name__)
T = TypeVar("T")

DIO_OUTPUT_LOW = 4
DIO_OUTPUT_HIGH = 5


@dataclass(frozen=True)
class XBeeTransportConfig:
    """Tuning of the XBee transport.

    Attributes:
        command_timeout_s: digi-xbee sync-ops timeout per remote command; for sleeping
            landmarks set it above the sleep period (SP) plus a margin.
        discovery_timeout_s: longest wait for node discovery to finish.
        health_interval_s: how often the port's presence is checked.
        reopen_initial_s, reopen_max_s: backoff between reopen attempts (doubling).
        open_timeout_s: digi-xbee's wait for each reply to a local AT command while it opens
            the port (a module answers in milliseconds), seconds.
        open_tries: attempts of one open, made at once when a reply was lost (a noisy
            line), before the backoff of `reopen_*` takes over.
        pipelined: write remote commands without waiting and match the replies by frame id
            (`ReplyRouter`), so that the gateway's `max_in_flight` commands share the air;
            False: one synchronous digi-xbee call at a time.
    """

    command_timeout_s: float = 1.0
    discovery_timeout_s: float = 10.0
    health_interval_s: float = 0.25
    reopen_initial_s: float = 0.1
    reopen_max_s: float = 5.0
    open_timeout_s: float = 1.0
    open_tries: int = 3
    pipelined: bool = False


def _st_value(seconds: float) -> bytes:
    """XBee `ST` in milliseconds, two bytes; ValueError outside 1 .. 65534 ms."""
    ms = round(seconds * 1000.0)
    if not 1 <= ms <= 0xFFFE:
        raise ValueError(f"set_awake_time: ST is 1 .. 65534 ms, got {seconds} s")
    return ms.to_bytes(2, "big")


class XBeeTransport(StateReporter):
    """`Transport` over a local XBee coordinator in API mode (AP=1 or 2).

    Args:
        port: serial device path, e.g. "/dev/ttyUSB0".
        baud: serial baud rate (the module's BD setting).
        pin: the DIO pin driving each landmark's LED ("D0".."D9" or "P0".."P9").
        config: timeouts and backoff.
    """

    def __init__(
        self,
        port: str,
        baud: int = DEFAULT_BAUD,
        *,
        pin: str = "D4",
        config: XBeeTransportConfig | None = None,
    ) -> None:
        if len(pin) != 2 or pin[0] not in "DP" or not pin[1].isdigit():
            raise ValueError(f"XBee LED pin {pin!r}: expected D0..D9 or P0..P9")
        super().__init__()
        self.on_state_change(lambda state: log.info("xbee %s: %s", port, state))
        self.port = port
        self.baud = baud
        self.pin = pin
        self.config = config or XBeeTransportConfig()
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="xbee")
        self._device: XBeeDevice | None = None
        self._remotes: dict[str, RemoteXBeeDevice] = {}
        self._tasks: set[asyncio.Task[None]] = set()
        self.reopen_count = 0
        self.link_stats = LinkStats()
        self.replies = ReplyRouter()

    async def _call(self, fn: Callable[..., T], *args: Any) -> T:
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._executor, fn, *args)

    # -- open / close / reopen -------------------------------------------------------------
    def _open_device(self) -> XBeeDevice:
        """Open the port, retrying at once (up to `open_tries`) when a reply to one of
        digi-xbee's local AT commands was lost; other failures raise at once."""
        for attempt in range(1, self.config.open_tries + 1):
            try:
                return self._open_once()
            except (TimeoutException, InvalidOperatingModeException) as exc:
                if attempt == self.config.open_tries or self._state == "closed":
                    raise
                log.info(
                    "xbee %s: open attempt %d lost a reply (%s); again", self.port, attempt, exc
                )
        raise AssertionError("unreachable")  # the loop returns or raises

    def _open_once(self) -> XBeeDevice:
        device = XBeeDevice(self.port, self.baud)
        try:
            device.set_sync_ops_timeout(self.config.open_timeout_s)
            device.open()
            device.set_sync_ops_timeout(self.config.command_timeout_s)
            device.add_packet_received_callback(self.link_stats.on_packet)
            device.add_packet_received_callback(self.replies.on_packet)
            if self._state == "closed":  # close() was called while this thread was opening
                raise TransportUnavailable(f"XBee on {self.port} closed while opening")
        except BaseException:
            with contextlib.suppress(Exception):
                device.close()
            raise
        return device

    def _close_device(self, device: XBeeDevice | None) -> None:
        if device is not None:
            with contextlib.suppress(Exception):
                device.close()

    async def open(self) -> None:
        """Open the port; on failure keep retrying in the background and raise.

        Raises:
            TransportUnavailable: the first attempt failed (state is then "reopening").
        """
        if self._state in ("open", "opening", "reopening"):
            return
        self._set_state("opening")
        self.link_stats.attach()
        try:
            self._device = await self._call(self._open_device)
        except Exception as exc:
            self._set_state("reopening")
            self._start(self._reopen_loop())
            raise TransportUnavailable(f"cannot open XBee on {self.port}: {exc}") from exc
        self._remotes.clear()
        self._set_state("open")
        self._start(self._health_loop())

    async def close(self) -> None:
        """Stop the background tasks and close the port; idempotent."""
        self._set_state("closed")
        for task in list(self._tasks):
            task.cancel()
        for task in list(self._tasks):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        device, self._device = self._device, None
        await self._call(self._close_device, device)
        self.link_stats.detach()
        self._executor.shutdown(wait=True)
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="xbee")

    def _start(self, coro: Any) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _health_loop(self) -> None:
        while self._state == "open":
            await asyncio.sleep(self.config.health_interval_s)
            if self._state == "open" and not os.path.exists(self.port):
                await self._lost("port disappeared")
                return

    async def _lost(self, why: str) -> None:
        if self._state != "open":
            return
        log.warning("xbee %s lost (%s); reopening", self.port, why)
        self._set_state("reopening")
        device, self._device = self._device, None
        self._remotes.clear()
        await self._call(self._close_device, device)
        self._start(self._reopen_loop())

    async def _reopen_loop(self) -> None:
        self._set_state("reopening")
        delay = self.config.reopen_initial_s
        while self._state == "reopening":
            await asyncio.sleep(delay)
            delay = min(2.0 * delay, self.config.reopen_max_s)
            if not os.path.exists(self.port):
                continue
            try:
                device = await self._call(self._open_device)
            except Exception as exc:
                log.info("xbee %s reopen failed: %s", self.port, exc)
                continue
            if self._state != "reopening":
                await self._call(self._close_device, device)
                return
            self._device = device
            self.reopen_count += 1
            self._set_state("open")
            self._start(self._health_loop())
            return

    # -- commands ----------------------------------------------------------------------------
    def _remote(self, address: str) -> RemoteXBeeDevice:
        device = self._device
        if device is None:
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")
        remote = self._remotes.get(address)
        if remote is None:
            remote = RemoteXBeeDevice(device, XBee64BitAddress.from_hex_string(address))
            remote.set_sync_ops_timeout(self.config.command_timeout_s)
            self._remotes[address] = remote
        return remote

    async def _remote_call(self, address: str, fn: Callable[[RemoteXBeeDevice], T]) -> T:
        address = normalize_address(address)
        if self._state != "open":
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")

        def run() -> T:
            return fn(self._remote(address))

        try:
            return await self._call(run)
        except TimeoutException as exc:
            raise RadioTimeout(address) from exc
        except ATCommandException as exc:
            status = getattr(exc.status, "code", exc.status)
            raise RemoteCommandError(address, status, f"radio {address}: {exc}") from exc
        except TransportUnavailable:
            raise
        except Exception as exc:  # serial write failed, interface closed: the port is gone
            await self._lost(str(exc))
            raise TransportUnavailable(f"XBee on {self.port}: {exc}") from exc

    async def set_pin(self, address: str, high: bool) -> None:
        value = bytearray((DIO_OUTPUT_HIGH if high else DIO_OUTPUT_LOW,))
        if self.config.pipelined:
            await self._pipelined(address, self.pin, bytes(value))
            return
        await self._remote_call(address, lambda r: r.set_parameter(self.pin, value))

    async def set_awake_time(self, address: str, seconds: float) -> None:
        value = bytearray(_st_value(seconds))
        if self.config.pipelined:
            await self._pipelined(address, "ST", bytes(value))
            return
        await self._remote_call(address, lambda r: r.set_parameter("ST", value))

    async def read_supply_mv(self, address: str) -> int:
        if self.config.pipelined:
            reply = await self._pipelined(address, "%V", b"")
            return int.from_bytes(reply.value, "big")
        raw = await self._remote_call(address, lambda r: r.get_parameter("%V"))
        return int.from_bytes(bytes(raw), "big")

    def _send_remote(
        self, address: str, command: str, parameter: bytes, future: asyncio.Future[RemoteReply]
    ) -> int:
        device = self._device
        if device is None:
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")
        frame_id = int(device.get_next_frame_id())
        while self.replies.in_use(frame_id):
            frame_id = int(device.get_next_frame_id())
        self.replies.expect(frame_id, address, command, future)
        packet = RemoteATCommandPacket(
            frame_id,
            XBee64BitAddress.from_hex_string(address),
            XBee16BitAddress.UNKNOWN_ADDRESS,
            RemoteATCmdOptions.APPLY_CHANGES.value,
            command,
            parameter=bytearray(parameter) if parameter else None,
            op_mode=device.operating_mode,
        )
        try:
            device.send_packet(packet, sync=False)
        except BaseException:
            self.replies.forget(frame_id)
            raise
        return frame_id

    async def _pipelined(self, address: str, command: str, parameter: bytes) -> RemoteReply:
        address = normalize_address(address)
        if self._state != "open":
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")
        future: asyncio.Future[RemoteReply] = asyncio.get_running_loop().create_future()
        try:
            frame_id = await self._call(self._send_remote, address, command, parameter, future)
        except TransportUnavailable:
            raise
        except Exception as exc:  # the write failed: the port is gone
            await self._lost(str(exc))
            raise TransportUnavailable(f"XBee on {self.port}: {exc}") from exc
        try:
            reply = await asyncio.wait_for(future, self.config.command_timeout_s)
        except TimeoutError:
            self.replies.forget(frame_id)
            raise RadioTimeout(address) from None
        if reply.status != 0:
            raise RemoteCommandError(address, reply.status)
        return reply

    async def read_pin(self, address: str) -> bool:
        """`BroadcastTransport.read_pin`: the LED pin's setting (5: output high)."""
        if self.config.pipelined:
            reply = await self._pipelined(address, self.pin, b"")
            raw = reply.value
        else:
            raw = bytes(await self._remote_call(address, lambda r: r.get_parameter(self.pin)))
        return bool(raw) and raw[-1] == DIO_OUTPUT_HIGH

    async def broadcast_pin(self, high: bool) -> None:
        """`BroadcastTransport.broadcast_pin`: as `broadcast_awake_time`, for the LED pin."""
        await self._broadcast(self.pin, bytes((DIO_OUTPUT_HIGH if high else DIO_OUTPUT_LOW,)))

    async def broadcast_awake_time(self, seconds: float) -> None:
        """`BroadcastTransport.broadcast_awake_time`: a remote `ST` to the broadcast address
        with frame id 0 (no answer asked for: Digi's guides say a broadcast remote AT
        command gets at most one, and is not acknowledged)."""
        await self._broadcast("ST", _st_value(seconds))

    async def _broadcast(self, command: str, value: bytes) -> None:
        if self._state != "open":
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")

        def send() -> None:
            device = self._device
            if device is None:
                raise TransportUnavailable(f"XBee on {self.port} is {self._state}")
            packet = RemoteATCommandPacket(
                0,
                XBee64BitAddress.BROADCAST_ADDRESS,
                XBee16BitAddress.UNKNOWN_ADDRESS,
                RemoteATCmdOptions.APPLY_CHANGES.value,
                command,
                parameter=bytearray(value),
                op_mode=device.operating_mode,
            )
            device.send_packet(packet, sync=False)

        try:
            await self._call(send)
        except TransportUnavailable:
            raise
        except Exception as exc:  # the write failed: the port is gone
            await self._lost(str(exc))
            raise TransportUnavailable(f"XBee on {self.port}: {exc}") from exc

    def _discover(self) -> list[DiscoveredRadio]:
        device = self._device
        if device is None:
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")
        net = device.get_network()
        net.clear()
        net.start_discovery_process()
        deadline = time.monotonic() + self.config.discovery_timeout_s
        while net.is_discovery_running() and time.monotonic() < deadline:
            time.sleep(0.02)
        if net.is_discovery_running():
            net.stop_discovery_process()
        own = str(device.get_64bit_addr()).upper()
        found = []
        for remote in net.get_devices():
            address = str(remote.get_64bit_addr()).upper()
            if address != own:
                found.append(DiscoveredRadio(address, remote.get_node_id() or ""))
        return sorted(found, key=lambda r: r.address)

    async def discover(self) -> list[DiscoveredRadio]:
        if self._state != "open":
            raise TransportUnavailable(f"XBee on {self.port} is {self._state}")
        try:
            return await self._call(self._discover)
        except TransportUnavailable:
            raise
        except Exception as exc:
            await self._lost(str(exc))
            raise TransportUnavailable(f"XBee on {self.port}: {exc}") from exc
