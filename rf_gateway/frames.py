"""XBee API frames: pure bytes <-> dataclass functions and a stream parser.

Frame layout (Digi API mode 1): 0x7E, length (2 bytes, big-endian, of the frame data),
frame data (frame type, then its fields), checksum = 0xFF - (sum of frame data & 0xFF).
API mode 2 ("escaped") additionally escapes 0x7E, 0x7D, 0x11 and 0x13 after the start
delimiter as 0x7D followed by the byte XOR 0x20.

The incremental parser for a byte stream is `rf_gateway.frame_parser.StreamParser`.
"""

from __future__ import annotations

from dataclasses import dataclass

START = 0x7E
ESCAPE = 0x7D
XON = 0x11
XOFF = 0x13
ESCAPED_BYTES = frozenset({START, ESCAPE, XON, XOFF})

LOCAL_AT = 0x08
LOCAL_AT_QUEUED = 0x09
TRANSMIT_REQUEST = 0x10
REMOTE_AT = 0x17
AT_RESPONSE = 0x88
TRANSMIT_STATUS = 0x8B
REMOTE_AT_RESPONSE = 0x97

BROADCAST_16 = 0xFFFE
REMOTE_APPLY_CHANGES = 0x02


@dataclass(frozen=True)
class LocalAtCommand:
    """Local AT command (0x08), or queued parameter value (0x09) when `queued`."""

    frame_id: int
    command: str
    parameter: bytes = b""
    queued: bool = False


@dataclass(frozen=True)
class AtResponse:
    """Local AT command response (0x88); status 0 OK."""

    frame_id: int
    command: str
    status: int
    data: bytes = b""


@dataclass(frozen=True)
class RemoteAtCommand:
    """Remote AT command request (0x17); `address64` is the destination."""

    frame_id: int
    address64: int
    command: str
    parameter: bytes = b""
    address16: int = BROADCAST_16
    options: int = REMOTE_APPLY_CHANGES


@dataclass(frozen=True)
class RemoteAtResponse:
    """Remote AT command response (0x97); status 4 = transmission failure."""

    frame_id: int
    address64: int
    address16: int
    command: str
    status: int
    data: bytes = b""


@dataclass(frozen=True)
class TransmitRequest:
    """Transmit request (0x10) of `payload` to `address64`."""

    frame_id: int
    address64: int
    payload: bytes
    address16: int = BROADCAST_16
    radius: int = 0
    options: int = 0


@dataclass(frozen=True)
class TransmitStatus:
    """Transmit status (0x8B); delivery_status 0 = success, 0x21 = network ACK failure."""

    frame_id: int
    address16: int
    retries: int
    delivery_status: int
    discovery_status: int = 0


@dataclass(frozen=True)
class UnknownFrame:
    """A frame whose type this module does not decode (kept, counted, skipped)."""

    frame_type: int
    data: bytes


ApiFrame = (
    LocalAtCommand
    | AtResponse
    | RemoteAtCommand
    | RemoteAtResponse
    | TransmitRequest
    | TransmitStatus
    | UnknownFrame
)


@dataclass(frozen=True)
class NodeInfo:
    """One node discovery (ND) reply: the payload of a 0x88 "ND" response.

    Attributes:
        address16, address64: the node's addresses.
        node_id: its NI string.
        parent16: parent's 16-bit address (0xFFFE when none).
        device_type: 0 coordinator, 1 router, 2 end device.
    """

    address16: int
    address64: int
    node_id: str
    parent16: int = BROADCAST_16
    device_type: int = 1
    status: int = 0
    profile_id: int = 0xC105
    manufacturer_id: int = 0x101E


def checksum(frame_data: bytes) -> int:
    """API checksum of `frame_data`: 0xFF minus the low byte of the sum."""
    return 0xFF - (sum(frame_data) & 0xFF)


def escape(data: bytes) -> bytes:
    """API mode 2 escaping of the bytes that follow the start delimiter."""
    out = bytearray()
    for b in data:
        if b in ESCAPED_BYTES:
            out += bytes((ESCAPE, b ^ 0x20))
        else:
            out.append(b)
    return bytes(out)


def wrap(frame_data: bytes, *, escaped: bool = False) -> bytes:
    """A whole frame on the wire (delimiter, length, data, checksum) around `frame_data`."""
    if not 0 < len(frame_data) <= 0xFFFF:
        raise ValueError(f"frame data length {len(frame_data)} outside 1..65535")
    body = len(frame_data).to_bytes(2, "big") + frame_data + bytes((checksum(frame_data),))
    return bytes((START,)) + (escape(body) if escaped else body)


def _cmd(data: bytes) -> str:
    return data.decode("ascii", errors="replace")


def _cmd_bytes(command: str) -> bytes:
    raw = command.encode("ascii")
    if len(raw) != 2:
        raise ValueError(f"AT command {command!r} is not two ASCII characters")
    return raw


def encode(frame: ApiFrame) -> bytes:
    """Frame data (type byte first, no delimiter/length/checksum) of `frame`."""
    if isinstance(frame, LocalAtCommand):
        kind = LOCAL_AT_QUEUED if frame.queued else LOCAL_AT
        return bytes((kind, frame.frame_id)) + _cmd_bytes(frame.command) + frame.parameter
    if isinstance(frame, AtResponse):
        head = bytes((AT_RESPONSE, frame.frame_id)) + _cmd_bytes(frame.command)
        return head + bytes((frame.status,)) + frame.data
    if isinstance(frame, RemoteAtCommand):
        return (
            bytes((REMOTE_AT, frame.frame_id))
            + frame.address64.to_bytes(8, "big")
            + frame.address16.to_bytes(2, "big")
            + bytes((frame.options,))
            + _cmd_bytes(frame.command)
            + frame.parameter
        )
    if isinstance(frame, RemoteAtResponse):
        return (
            bytes((REMOTE_AT_RESPONSE, frame.frame_id))
            + frame.address64.to_bytes(8, "big")
            + frame.address16.to_bytes(2, "big")
            + _cmd_bytes(frame.command)
            + bytes((frame.status,))
            + frame.data
        )
    if isinstance(frame, TransmitRequest):
        return (
            bytes((TRANSMIT_REQUEST, frame.frame_id))
            + frame.address64.to_bytes(8, "big")
            + frame.address16.to_bytes(2, "big")
            + bytes((frame.radius, frame.options))
            + frame.payload
        )
    if isinstance(frame, TransmitStatus):
        return (
            bytes((TRANSMIT_STATUS, frame.frame_id))
            + frame.address16.to_bytes(2, "big")
            + bytes((frame.retries, frame.delivery_status, frame.discovery_status))
        )
    return bytes((frame.frame_type,)) + frame.data


_MIN_LEN = {
    LOCAL_AT: 4,
    LOCAL_AT_QUEUED: 4,
    AT_RESPONSE: 5,
    REMOTE_AT: 15,
    REMOTE_AT_RESPONSE: 15,
    TRANSMIT_REQUEST: 14,
    TRANSMIT_STATUS: 7,
}


def decode(data: bytes) -> ApiFrame:
    """Dataclass of frame data `data` (type byte first).

    Unknown types, and known types too short for their fields, come back as `UnknownFrame`.
    """
    if not data:
        raise ValueError("empty frame data")
    kind = data[0]
    if len(data) < _MIN_LEN.get(kind, 1 << 30):
        return UnknownFrame(kind, bytes(data[1:]))
    if kind in (LOCAL_AT, LOCAL_AT_QUEUED):
        return LocalAtCommand(data[1], _cmd(data[2:4]), bytes(data[4:]), kind == LOCAL_AT_QUEUED)
    if kind == AT_RESPONSE:
        return AtResponse(data[1], _cmd(data[2:4]), data[4], bytes(data[5:]))
    if kind == REMOTE_AT:
        return RemoteAtCommand(
            frame_id=data[1],
            address64=int.from_bytes(data[2:10], "big"),
            address16=int.from_bytes(data[10:12], "big"),
            options=data[12],
            command=_cmd(data[13:15]),
            parameter=bytes(data[15:]),
        )
    if kind == REMOTE_AT_RESPONSE:
        return RemoteAtResponse(
            frame_id=data[1],
            address64=int.from_bytes(data[2:10], "big"),
            address16=int.from_bytes(data[10:12], "big"),
            command=_cmd(data[12:14]),
            status=data[14],
            data=bytes(data[15:]),
        )
    if kind == TRANSMIT_REQUEST:
        return TransmitRequest(
            frame_id=data[1],
            address64=int.from_bytes(data[2:10], "big"),
            address16=int.from_bytes(data[10:12], "big"),
            radius=data[12],
            options=data[13],
            payload=bytes(data[14:]),
        )
    if kind == TRANSMIT_STATUS:
        return TransmitStatus(data[1], int.from_bytes(data[2:4], "big"), data[4], data[5], data[6])
    return UnknownFrame(kind, bytes(data[1:]))


def encode_node_info(node: NodeInfo) -> bytes:
    """Payload of an ND reply (MY, SH, SL, NI, 0x00, parent, type, status, profile, mfr)."""
    return (
        node.address16.to_bytes(2, "big")
        + node.address64.to_bytes(8, "big")
        + node.node_id.encode("ascii")
        + b"\x00"
        + node.parent16.to_bytes(2, "big")
        + bytes((node.device_type, node.status))
        + node.profile_id.to_bytes(2, "big")
        + node.manufacturer_id.to_bytes(2, "big")
    )


def decode_node_info(payload: bytes) -> NodeInfo:
    """Parse an ND reply payload; ValueError names what is missing."""
    end = payload.find(b"\x00", 10)
    if len(payload) < 11 or end < 0 or len(payload) < end + 9:
        raise ValueError(f"ND reply of {len(payload)} bytes is too short or has no NI end")
    return NodeInfo(
        address16=int.from_bytes(payload[0:2], "big"),
        address64=int.from_bytes(payload[2:10], "big"),
        node_id=payload[10:end].decode("ascii", errors="replace"),
        parent16=int.from_bytes(payload[end + 1 : end + 3], "big"),
        device_type=payload[end + 3],
        status=payload[end + 4],
        profile_id=int.from_bytes(payload[end + 5 : end + 7], "big"),
        manufacturer_id=int.from_bytes(payload[end + 7 : end + 9], "big"),
    )
