"""An XBee 3 Zigbee coordinator emulated on a pseudo-terminal, with emulated landmarks.

It speaks real API frames (`rf_gateway.frames`) to whatever opens its port (digi-xbee through
pyserial in the tests and the benchmark), answers the local AT commands digi-xbee sends on
open (0x08 and 0x09: AP, HV, VR, SH, SL, NI, MY, CE, ...), remote AT commands (0x17 -> 0x97)
to emulated landmarks (DIO pin levels, `%V` supply voltage; to the broadcast address
0x000000000000FFFF every reachable landmark applies it, one answer at most), transmit
requests (0x10 -> 0x8B) and node discovery (N?, NT, ND). Faults are injected on the replies
to remote commands: drop, delay, corrupt, duplicate, garbage bytes, truncated and unknown
frames. `pull_cable()` closes the pseudo-terminal (the port disappears) and `plug_in()`
brings a new one back at the same path.

Not a test double of digi-xbee: digi-xbee runs unmodified against it.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import random
import select
import threading
import time
import tty
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from rf_gateway import frames as fr
from rf_gateway.frame_parser import StreamParser

AP_API = 1
AP_ESCAPED = 2
HV_XBEE3 = bytes((0x42, 0x00))
VR_ZIGBEE = bytes((0x10, 0x0B))
STATUS_OK = 0
STATUS_INVALID_COMMAND = 2
STATUS_TX_FAILURE = 4
BROADCAST_64 = 0xFFFF


@dataclass
class EmulatedRemote:
    """One emulated landmark radio.

    Attributes:
        address: 64-bit address, 16 hex digits.
        node_id: NI string.
        supply_mv: what `%V` answers, millivolts.
        reachable: False: the coordinator answers status 4 (transmission failure).
        silent: True: no answer at all (the host times out).
        delay_s: extra reply latency of this radio, seconds.
        sleep_period_s: the radio sleeps in cycles of this period (XBee cyclic sleep, `SP`):
            a command waits at its parent until the next wake-up, at `sleep_phase_s` into
            each cycle (None: always awake).
        late_replies: the next this many replies come `late_delay_s` late (a reply crossing
            the host's retry).
        pins: DIO configuration values by command ("D4" -> 5 means output high).
        settings: sleep settings written (`ST`, `SP`, `SM`, `SN` -> value).
        applied: every parameter write applied, as (command, value) in order.
    """

    address: str
    node_id: str = ""
    supply_mv: int = 3000
    reachable: bool = True
    silent: bool = False
    delay_s: float = 0.0
    sleep_period_s: float | None = None
    sleep_phase_s: float = 0.0
    late_replies: int = 0
    late_delay_s: float = 0.5
    pins: dict[str, int] = field(default_factory=dict)
    settings: dict[str, int] = field(default_factory=dict)
    applied: list[tuple[str, int]] = field(default_factory=list)

    @property
    def address64(self) -> int:
        return int(self.address, 16)

    def wake_delay_s(self, now_s: float) -> float:
        """Seconds from `now_s` (monotonic) to the radio's next wake-up (0 when awake)."""
        if self.sleep_period_s is None:
            return 0.0
        return (self.sleep_phase_s - now_s) % self.sleep_period_s


@dataclass
class FaultConfig:
    """Faults injected on replies to remote commands (probabilities per reply, seconds).

    Attributes:
        drop: reply not sent.
        duplicate: reply sent twice.
        corrupt: one byte of the reply flipped (bad checksum on the host).
        garbage: random bytes written before the reply.
        truncated: a cut-short frame written before the reply.
        unknown: a frame of an unknown type (0x3F) written before the reply.
        delay_s: base reply latency; jitter_s: uniform extra latency in [0, jitter_s).
        seed: of the fault generator.
    """

    drop: float = 0.0
    duplicate: float = 0.0
    corrupt: float = 0.0
    garbage: float = 0.0
    truncated: float = 0.0
    unknown: float = 0.0
    delay_s: float = 0.001
    jitter_s: float = 0.0
    seed: int = 0


class XBeeEmulator:
    """The coordinator: `start()`, then open `port` (a symlink to the pty) with digi-xbee.

    Args:
        port: path of the symlink created to the pseudo-terminal's slave side.
        remotes: the emulated landmarks.
        escaped: API mode 2 (AP=2) instead of 1.
        faults: fault injection on remote replies (mutable while running).
        address: the coordinator's own 64-bit address.
        tx_failure_delay_s: how long before status 4 is reported for an unreachable remote.
    """

    def __init__(
        self,
        port: str | Path,
        remotes: list[EmulatedRemote] | tuple[EmulatedRemote, ...] = (),
        *,
        escaped: bool = False,
        faults: FaultConfig | None = None,
        address: str = "0013A20040000001",
        node_id: str = "COORDINATOR",
        tx_failure_delay_s: float = 0.01,
    ) -> None:
        self.port = Path(port)
        self.remotes = {r.address.upper(): r for r in remotes}
        self.escaped = escaped
        self.faults = faults or FaultConfig()
        self.address = address
        self.node_id = node_id
        self.tx_failure_delay_s = tx_failure_delay_s
        self.nt_100ms = 0x10
        self.drop_local_replies = 0
        """Replies to local AT commands still to lose (a noisy line while the host opens)."""
        self.parser = StreamParser(escaped=escaped)
        self.counts: Counter[str] = Counter()
        self._rng = random.Random(self.faults.seed)
        self._lock = threading.Lock()
        self._outbox: list[tuple[float, int, bytes]] = []
        self._seq = 0
        self._master: int | None = None
        self._slave: int | None = None
        self._wake_r, self._wake_w = os.pipe()
        self._stop = False
        self._thread: threading.Thread | None = None

    # -- lifecycle ---------------------------------------------------------------------
    def start(self) -> XBeeEmulator:
        """Create the pty and the symlink and start serving; returns self."""
        self.plug_in()
        self._thread = threading.Thread(target=self._run, name="xbee-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving and remove the pty and the symlink."""
        self._stop = True
        self._wake()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self.pull_cable()
        os.close(self._wake_r)
        os.close(self._wake_w)

    def __enter__(self) -> XBeeEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def pull_cable(self) -> None:
        """The USB cable is pulled: close the pty (the host's reads fail) and drop the path."""
        with self._lock:
            for fd in (self._master, self._slave):
                if fd is not None:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self._master = self._slave = None
            self._outbox.clear()
            with contextlib.suppress(FileNotFoundError):
                self.port.unlink()
        self._wake()

    def plug_in(self) -> None:
        """The cable is back: a new pty behind the same port path."""
        with self._lock:
            if self._master is not None:
                return
            master, slave = os.openpty()
            tty.setraw(master)
            tty.setraw(slave)
            self._master, self._slave = master, slave
            self.parser = StreamParser(escaped=self.escaped)
            with contextlib.suppress(FileNotFoundError):
                self.port.unlink()
            self.port.symlink_to(os.ttyname(slave))
        self._wake()

    @property
    def plugged_in(self) -> bool:
        return self._master is not None

    def remote(self, address: str) -> EmulatedRemote:
        """The emulated remote with `address` (KeyError names it)."""
        try:
            return self.remotes[address.upper()]
        except KeyError:
            raise KeyError(f"no emulated remote {address}") from None

    def inject(self, raw: bytes, delay_s: float = 0.0) -> None:
        """Write raw bytes to the host after `delay_s` (garbage, hand-made frames)."""
        self._schedule(raw, delay_s)

    def send_frame(self, frame: fr.ApiFrame, delay_s: float = 0.0) -> None:
        """Send one API frame to the host."""
        self._schedule(fr.wrap(fr.encode(frame), escaped=self.escaped), delay_s)

    # -- the serving thread ------------------------------------------------------------
    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def _schedule(self, raw: bytes, delay_s: float) -> None:
        with self._lock:
            self._seq += 1
            heapq.heappush(self._outbox, (time.monotonic() + delay_s, self._seq, raw))
        self._wake()

    def _run(self) -> None:
        while not self._stop:
            with self._lock:
                master = self._master
                due = self._outbox[0][0] if self._outbox else None
            timeout = 0.2 if due is None else max(0.0, due - time.monotonic())
            fds = [self._wake_r] + ([master] if master is not None else [])
            try:
                readable, _, _ = select.select(fds, [], [], timeout)
            except (OSError, ValueError):
                continue
            if self._wake_r in readable:
                os.read(self._wake_r, 4096)
            if master is not None and master in readable:
                try:
                    data = os.read(master, 4096)
                except OSError:
                    data = b""
                for frame_data in self.parser.feed(data):
                    self._handle(fr.decode(frame_data))
            self._flush_due()

    def _flush_due(self) -> None:
        now = time.monotonic()
        with self._lock:
            while self._outbox and self._outbox[0][0] <= now:
                _, _, raw = heapq.heappop(self._outbox)
                if self._master is None:
                    continue
                try:
                    os.write(self._master, raw)
                except OSError:
                    self.counts["write_errors"] += 1

    # -- answering -----------------------------------------------------------------------
    def _reply(self, frame: fr.ApiFrame, delay_s: float = 0.0) -> None:
        self.send_frame(frame, delay_s)

    def _handle(self, frame: fr.ApiFrame) -> None:
        self.counts[type(frame).__name__] += 1
        if isinstance(frame, fr.LocalAtCommand):
            self._handle_local(frame)
        elif isinstance(frame, fr.RemoteAtCommand):
            self._handle_remote(frame)
        elif isinstance(frame, fr.TransmitRequest):
            self._handle_transmit(frame)
        else:
            self.counts["unknown_frames"] += 1

    def _local_value(self, command: str) -> bytes | None:
        values = {
            "AP": bytes((AP_ESCAPED if self.escaped else AP_API,)),
            "HV": HV_XBEE3,
            "VR": VR_ZIGBEE,
            "SH": bytes.fromhex(self.address[:8]),
            "SL": bytes.fromhex(self.address[8:]),
            "NI": self.node_id.encode("ascii"),
            "MY": bytes((0, 0)),
            "CE": bytes((1,)),
            "NT": bytes((self.nt_100ms,)),
            "N?": (self.nt_100ms * 100).to_bytes(2, "big"),
            "BR": bytes((1,)),
            "AO": bytes((0,)),
        }
        return values.get(command)

    def _handle_local(self, frame: fr.LocalAtCommand) -> None:
        cmd = frame.command
        if self.drop_local_replies > 0:
            self.drop_local_replies -= 1
            self.counts["dropped_local"] += 1
            return
        if cmd == "ND":
            self._node_discovery(frame.frame_id)
            return
        if cmd == "NT" and frame.parameter:
            self.nt_100ms = frame.parameter[-1]
        if frame.parameter or cmd in ("AC", "WR"):
            self._reply(fr.AtResponse(frame.frame_id, cmd, STATUS_OK))
            return
        value = self._local_value(cmd)
        status = STATUS_OK if value is not None else STATUS_INVALID_COMMAND
        self._reply(fr.AtResponse(frame.frame_id, cmd, status, value or b""))

    def _node_discovery(self, frame_id: int) -> None:
        delay = 0.0
        for remote in self.remotes.values():
            if not remote.reachable or remote.silent:
                continue
            delay += 0.002
            info = fr.NodeInfo(
                address16=0x1000 + len(remote.node_id),
                address64=remote.address64,
                node_id=remote.node_id,
                parent16=0,
            )
            self._reply(fr.AtResponse(frame_id, "ND", STATUS_OK, fr.encode_node_info(info)), delay)
        self._reply(fr.AtResponse(frame_id, "ND", STATUS_OK), delay + 0.005)

    def _remote_answer(
        self, remote: EmulatedRemote, frame: fr.RemoteAtCommand
    ) -> tuple[int, bytes]:
        cmd = frame.command
        if cmd == "%V":
            return STATUS_OK, remote.supply_mv.to_bytes(2, "big")
        if cmd == "NI":
            return STATUS_OK, remote.node_id.encode("ascii")
        if len(cmd) == 2 and cmd[0] in "DP" and cmd[1].isdigit():
            if frame.parameter:
                with self._lock:
                    remote.pins[cmd] = frame.parameter[-1]
                    remote.applied.append((cmd, frame.parameter[-1]))
                return STATUS_OK, b""
            return STATUS_OK, bytes((remote.pins.get(cmd, 0),))
        if cmd in ("ST", "SP", "SM", "SN"):  # sleep settings: recorded, not modelled
            if frame.parameter:
                value = int.from_bytes(frame.parameter, "big")
                with self._lock:
                    remote.settings[cmd] = value
                    remote.applied.append((cmd, value))
                return STATUS_OK, b""
            return STATUS_OK, remote.settings.get(cmd, 0).to_bytes(2, "big")
        if cmd in ("AC", "WR"):
            return STATUS_OK, b""
        return STATUS_INVALID_COMMAND, b""

    def _handle_remote(self, frame: fr.RemoteAtCommand) -> None:
        if frame.address64 == BROADCAST_64:  # every reachable remote applies it
            self.counts["broadcasts"] += 1
            answered = frame.frame_id == 0  # frame id 0: no answer asked for
            for each in list(self.remotes.values()):
                if each.reachable and not each.silent:
                    status, data = self._remote_answer(each, frame)
                    if not answered:  # one answer at most (Digi's guides)
                        answered = True
                        answer = fr.RemoteAtResponse(
                            frame.frame_id, each.address64, 0x1000, frame.command, status, data
                        )
                        self._faulty_reply(answer, each.delay_s)
            return
        remote = self.remotes.get(f"{frame.address64:016X}")
        if remote is None or not remote.reachable:
            self.counts["tx_failures"] += 1
            failure = fr.RemoteAtResponse(
                frame.frame_id, frame.address64, fr.BROADCAST_16, frame.command, STATUS_TX_FAILURE
            )
            self._reply(failure, self.tx_failure_delay_s)
            return
        if remote.silent:
            self.counts["silent"] += 1
            return
        with self._lock:  # replies still scheduled when this request came in
            waiting = len(self._outbox)
        self.counts["max_overlap"] = max(self.counts["max_overlap"], waiting)
        status, data = self._remote_answer(remote, frame)
        answer = fr.RemoteAtResponse(
            frame.frame_id, frame.address64, 0x1000, frame.command, status, data
        )
        delay = remote.delay_s + remote.wake_delay_s(time.monotonic())
        if remote.sleep_period_s is not None:
            self.counts["buffered_for_sleep"] += 1
        if remote.late_replies > 0:
            remote.late_replies -= 1
            delay += remote.late_delay_s
            self.counts["late"] += 1
        self._faulty_reply(answer, delay)

    def _handle_transmit(self, frame: fr.TransmitRequest) -> None:
        remote = self.remotes.get(f"{frame.address64:016X}")
        ok = remote is not None and remote.reachable and not remote.silent
        status = fr.TransmitStatus(frame.frame_id, 0x1000, 0, 0x00 if ok else 0x21)
        self._faulty_reply(status, remote.delay_s if remote else 0.0)

    def _faulty_reply(self, frame: fr.ApiFrame, extra_delay_s: float) -> None:
        f = self.faults
        rng = self._rng
        delay = f.delay_s + extra_delay_s + (rng.uniform(0.0, f.jitter_s) if f.jitter_s else 0.0)
        if rng.random() < f.garbage:
            self.counts["garbage_sent"] += 1
            noise = bytes(rng.choice((0x00, 0x55, 0xAA, 0x13, 0xFF)) for _ in range(7))
            self.inject(noise, delay)
        if rng.random() < f.truncated:
            self.counts["truncated_sent"] += 1
            whole = fr.wrap(fr.encode(frame), escaped=self.escaped)
            self.inject(whole[: len(whole) // 2], delay)
        if rng.random() < f.unknown:
            self.counts["unknown_sent"] += 1
            self.send_frame(fr.UnknownFrame(0x3F, b"\x01\x02\x03"), delay)
        if rng.random() < f.drop:
            self.counts["dropped"] += 1
            return
        raw = fr.wrap(fr.encode(frame), escaped=self.escaped)
        if rng.random() < f.corrupt:
            self.counts["corrupted"] += 1
            flipped = bytearray(raw)
            bad = flipped[-1] ^ 0x01
            flipped[-1] = bad if bad not in fr.ESCAPED_BYTES else flipped[-1] ^ 0x04
            raw = bytes(flipped)
        self.inject(raw, delay)
        if rng.random() < f.duplicate:
            self.counts["duplicated"] += 1
            self.inject(raw, delay + 0.001)
