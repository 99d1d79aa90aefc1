"""The small protocol every radio transport implements, and the radio spec parser.

A transport moves single commands to single remote radios; retries, priorities, in-flight
limits and LED bookkeeping live in the `Gateway` above it.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal, Protocol, runtime_checkable

TransportState = Literal["closed", "opening", "open", "reopening"]
TRANSPORT_STATES: tuple[TransportState, ...] = ("closed", "opening", "open", "reopening")

_ADDRESS_RE = re.compile(r"^[0-9A-F]{16}$")
DEFAULT_BAUD = 9600


def normalize_address(address: str, *, source: str = "radio address") -> str:
    """Canonical 64-bit radio address: 16 uppercase hex digits.

    Accepts lower case, a `0x` prefix and `:`/`-`/space separators (as printed on labels).

    Raises:
        ValueError: naming `source` and the bad value.
    """
    if not isinstance(address, str):
        raise ValueError(f"{source}: {address!r} is not a string of 16 hex digits")
    text = address.strip().upper()
    text = text.removeprefix("0X")
    text = re.sub(r"[\s:\-]", "", text)
    if not _ADDRESS_RE.match(text):
        raise ValueError(f"{source}: {address!r} is not a 64-bit address (16 hex digits)")
    return text


def normalize_landmark_radios(landmarks: Mapping[int, str]) -> dict[int, str]:
    """Landmark id -> canonical radio address; ValueError names a bad or shared address."""
    out: dict[int, str] = {}
    seen: dict[str, int] = {}
    for lid, address in landmarks.items():
        canonical = normalize_address(address, source=f"landmark {lid} radio")
        if canonical in seen:
            raise ValueError(f"landmarks {seen[canonical]} and {lid} share radio {canonical}")
        seen[canonical] = int(lid)
        out[int(lid)] = canonical
    return out


@dataclass(frozen=True)
class DiscoveredRadio:
    """A radio that answered node discovery.

    Attributes:
        address: 64-bit address, 16 uppercase hex digits.
        node_id: its node identifier (NI), possibly empty.
    """

    address: str
    node_id: str = ""


class StateReporter:
    """The `state` property and state-change listeners shared by the transports."""

    def __init__(self) -> None:
        self._state: TransportState = "closed"
        self._listeners: list[Callable[[TransportState], None]] = []

    @property
    def state(self) -> TransportState:
        return self._state

    def on_state_change(self, callback: Callable[[TransportState], None]) -> None:
        """Call `callback(state)` (on the event loop) at every state change."""
        self._listeners.append(callback)

    def _set_state(self, state: TransportState) -> None:
        if state == self._state:
            return
        self._state = state
        for callback in list(self._listeners):
            callback(state)


@runtime_checkable
class Transport(Protocol):
    """One radio link to the landmarks (simulated site or XBee coordinator).

    Every method is a coroutine and may be called concurrently; a transport serialises what
    its hardware cannot do in parallel.
    """

    @property
    def state(self) -> TransportState:
        """ "closed", "opening", "open" or "reopening" (port lost, trying again)."""
        ...

    async def open(self) -> None:
        """Open the link. Raises TransportUnavailable when it cannot."""
        ...

    async def close(self) -> None:
        """Close the link; idempotent."""
        ...

    async def set_pin(self, address: str, high: bool) -> None:
        """Drive the landmark's LED pin high (LED on) or low and wait for the acknowledgement.

        Raises:
            RadioTimeout: no answer within the transport's command timeout.
            RemoteCommandError: the command was refused or could not be delivered.
            TransportUnavailable: the link is not open.
        """
        ...

    async def read_supply_mv(self, address: str) -> int:
        """The landmark's supply voltage in millivolts (remote `%V`); raises as `set_pin`."""
        ...

    async def set_awake_time(self, address: str, seconds: float) -> None:
        """Set how long a sleeping landmark stays awake after each message (remote `ST`,
        milliseconds, applied at once, not saved); raises as `set_pin`."""
        ...

    async def discover(self) -> list[DiscoveredRadio]:
        """Every radio that answers node discovery (the coordinator excluded)."""
        ...


@runtime_checkable
class BroadcastTransport(Protocol):
    """A transport that can also send one remote AT command to every landmark at once (the
    broadcast address, unacknowledged): a sleeping landmark's parent buffers one broadcast
    for all its children and each takes it at its next poll, so the whole site hears one
    frame within a sleep period instead of one command per landmark through the
    coordinator's few in-flight slots. Nothing confirms who got it (Digi's guides: a
    broadcast is not acknowledged and a remote AT command to it gets at most one answer),
    so what it set is read back landmark by landmark (`read_pin`). One broadcast at a time:
    a parent keeps only the newest."""

    async def broadcast_pin(self, high: bool) -> None:
        """Drive every landmark's LED pin by one unacknowledged broadcast. Raises
        TransportUnavailable."""
        ...

    async def broadcast_awake_time(self, seconds: float) -> None:
        """Send `ST` (seconds, applied at once, not saved) to every landmark by one
        unacknowledged broadcast. Raises TransportUnavailable."""
        ...

    async def read_pin(self, address: str) -> bool:
        """Whether the landmark's LED pin is high (remote query of the pin's setting);
        raises as `Transport.set_pin`."""
        ...


@dataclass(frozen=True)
class SimRadioSpec:
    """`--radio sim`: the virtual site's simulated radio."""

    kind: Literal["sim"] = "sim"


@dataclass(frozen=True)
class XBeeRadioSpec:
    """`--radio xbee:PORT[@BAUD]`: an XBee coordinator on a serial port."""

    port: str
    baud: int = DEFAULT_BAUD
    kind: Literal["xbee"] = "xbee"


RadioSpec = SimRadioSpec | XBeeRadioSpec


def parse_radio_spec(spec: str) -> RadioSpec:
    """Parse `sim`, `xbee:/dev/ttyUSB0` or `xbee:/dev/ttyUSB0@115200`.

    Raises:
        ValueError: naming the spec and what is wrong with it.
    """
    text = spec.strip()
    if text == "sim":
        return SimRadioSpec()
    if not text.startswith("xbee:"):
        raise ValueError(f"radio spec {spec!r}: expected 'sim' or 'xbee:PORT[@BAUD]'")
    rest = text.removeprefix("xbee:")
    port, sep, baud_text = rest.rpartition("@")
    if not sep:
        port, baud_text = rest, ""
    if not port:
        raise ValueError(f"radio spec {spec!r}: no serial port after 'xbee:'")
    if not baud_text:
        return XBeeRadioSpec(port=port)
    if not baud_text.isdigit() or int(baud_text) <= 0:
        raise ValueError(f"radio spec {spec!r}: baud rate {baud_text!r} is not a positive integer")
    return XBeeRadioSpec(port=port, baud=int(baud_text))
