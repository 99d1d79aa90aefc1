"""The reconnecting MQTT connection both ends use (the agent per robot, the server once):
connect with a last will, serve until the connection is lost, wait (0.2 s, doubling to
2 s) and connect again, until asked to stop. The one module of `fleet` that does I/O."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any

import aiomqtt

from fleet.broker import BrokerAddress, BrokerTls

log = logging.getLogger(__name__)
RECONNECT_S = (0.2, 2.0)
"""First and longest wait between connection attempts, seconds."""
KEEPALIVE_S = 10
"""MQTT keep-alive: a silent link is noticed after 1.5 x this (a closed socket at once)."""


class BrokerUnreachableError(ConnectionError):
    """The broker could not be reached (or refused the login) for the first connection."""


def tls_parameters(tls: BrokerTls | None) -> aiomqtt.TLSParameters | None:
    """aiomqtt's TLS settings for `tls` (None: plain TCP): the broker verified against the
    CA file (else the system's), this client's certificate presented when given."""
    if tls is None:
        return None
    return aiomqtt.TLSParameters(
        ca_certs=str(tls.ca_file) if tls.ca_file else None,
        certfile=str(tls.cert_file) if tls.cert_file else None,
        keyfile=str(tls.key_file) if tls.key_file else None,
        cert_reqs=ssl.CERT_REQUIRED,
        tls_version=ssl.PROTOCOL_TLS_CLIENT,
    )


def make_client(
    broker: BrokerAddress, identifier: str, will: aiomqtt.Will | None = None
) -> aiomqtt.Client:
    """A client of `broker` logging in as its user (password, TLS files), not yet connected
    (`async with` connects)."""
    return aiomqtt.Client(
        broker.host,
        broker.port,
        identifier=identifier,
        username=broker.username,
        password=broker.password,
        tls_params=tls_parameters(broker.tls),
        will=will,
        keepalive=KEEPALIVE_S,
        timeout=5.0,
    )


async def run_session(
    broker: BrokerAddress,
    *,
    identifier: str,
    will: Callable[[], aiomqtt.Will],
    serve: Callable[[aiomqtt.Client], Awaitable[bool]],
    stop: asyncio.Event,
    name: str,
    first_connect_s: float | None = None,
) -> None:
    """Connect to `broker` and `await serve(client)` until `stop` is set; `serve` returns
    True to end for good, False when the connection was lost (then it reconnects). `will`
    builds the last will for each attempt (VDA 5050 wills carry a fresh header).

    Raises:
        BrokerUnreachableError: no first connection within `first_connect_s` (None: keep
            trying; once connected, a lost connection is always retried).
    """
    wait = RECONNECT_S[0]
    t0 = asyncio.get_running_loop().time()
    connected = False
    while not stop.is_set():
        try:
            async with make_client(broker, identifier, will()) as client:
                connected = True
                wait = RECONNECT_S[0]
                if await serve(client):
                    return
                log.warning("%s: connection to %s lost; reconnecting", name, broker)
        except aiomqtt.MqttError as exc:
            late = asyncio.get_running_loop().time() - t0
            if not connected and first_connect_s is not None and late > first_connect_s:
                raise BrokerUnreachableError(
                    f"{name}: no connection to the broker {broker} in {first_connect_s:g} s: {exc}"
                ) from None
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
