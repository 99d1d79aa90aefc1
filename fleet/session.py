"""The reconnecting MQTT connection both ends use (the agent per robot, the server once):
connect with a last will, serve until the connection is lost, wait (0.2 s, doubling to
2 s) and connect again, until asked to stop. The one module of `fleet` that does I/O."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any

import aiomqtt

from fleet.broker import BrokerAddress

log = logging.getLogger(__name__)
RECONNECT_S = (0.2, 2.0)
"""First and longest wait between connection attempts, seconds."""
KEEPALIVE_S = 10
"""MQTT keep-alive: a silent link is noticed after 1.5 x this (a closed socket at once)."""


async def run_session(
    broker: BrokerAddress,
    *,
    identifier: str,
    will: Callable[[], aiomqtt.Will],
    serve: Callable[[aiomqtt.Client], Awaitable[bool]],
    stop: asyncio.Event,
    name: str,
) -> None:
    """Connect to `broker` and `await serve(client)` until `stop` is set; `serve` returns
    True to end for good, False when the connection was lost (then it reconnects). `will`
    builds the last will for each attempt (VDA 5050 wills carry a fresh header)."""
    wait = RECONNECT_S[0]
    while not stop.is_set():
        try:
            async with aiomqtt.Client(
                broker.host,
                broker.port,
                identifier=identifier,
                will=will(),
                keepalive=KEEPALIVE_S,
                timeout=5.0,
            ) as client:
                wait = RECONNECT_S[0]
                if await serve(client):
                    return
                log.warning("%s: connection to %s lost; reconnecting", name, broker)
        except aiomqtt.MqttError as exc:
            if wait == RECONNECT_S[0]:
                log.warning("%s: broker %s: %s; retrying", name, broker, exc)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), wait)
        wait = min(wait * 2, RECONNECT_S[1])


async def until_first_ends(*coros: Coroutine[Any, Any, object]) -> None:
    """Run the coroutines until one of them ends (a lost connection ends its receive loop),
    then cancel the others and wait for them, errors of the lost connection swallowed."""
    tasks = [asyncio.create_task(c) for c in coros]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError, aiomqtt.MqttError):
                await t
