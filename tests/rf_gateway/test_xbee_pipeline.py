from __future__ import annotations

import asyncio

from digi.xbee.models.address import XBee16BitAddress, XBee64BitAddress
from digi.xbee.models.status import ATCommandStatus
from digi.xbee.packets.common import RemoteATCommandResponsePacket

from rf_gateway.xbee_pipeline import RemoteReply, ReplyRouter

A1, A2 = "0013A20040A00001", "0013A20040A00002"


def reply(frame_id: int, address: str, command: str, status: int, value: bytes) -> object:
    return RemoteATCommandResponsePacket(
        frame_id,
        XBee64BitAddress.from_hex_string(address),
        XBee16BitAddress.from_hex_string("1000"),
        command,
        ATCommandStatus.get(status),
        comm_value=bytearray(value),
    )


def test_replies_are_matched_by_frame_id_address_and_command() -> None:
    async def main() -> tuple[RemoteReply, RemoteReply, ReplyRouter]:
        router = ReplyRouter()
        loop = asyncio.get_running_loop()
        f7, f8 = loop.create_future(), loop.create_future()
        router.expect(7, A1, "D4", f7)
        router.expect(8, A2, "%V", f8)
        router.on_packet(reply(8, A1, "%V", 0, b"\x0b\xb8"))  # right id, wrong radio
        router.on_packet(reply(7, A1, "D5", 0, b""))  # right id, wrong command
        router.on_packet(reply(9, A1, "D4", 0, b""))  # nobody waits: late
        router.on_packet(reply(8, A2, "%V", 0, b"\x0b\xb8"))
        router.on_packet(reply(7, A1, "D4", 4, b""))
        assert not router.in_use(7) and not router.in_use(8)
        return await f7, await f8, router

    r7, r8, router = asyncio.run(main())
    assert r7 == RemoteReply(4, b"")
    assert r8 == RemoteReply(0, b"\x0b\xb8")
    assert (router.mismatched, router.late_replies) == (2, 1)


def test_a_forgotten_request_makes_its_reply_late() -> None:
    async def main() -> tuple[bool, int]:
        router = ReplyRouter()
        fut = asyncio.get_running_loop().create_future()
        router.expect(3, A1, "D4", fut)
        router.forget(3)
        router.on_packet(reply(3, A1, "D4", 0, b""))
        await asyncio.sleep(0)
        return fut.done(), router.late_replies

    assert asyncio.run(main()) == (False, 1)
