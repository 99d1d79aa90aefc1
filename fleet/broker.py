"""Where the broker is: `mqtt://HOST[:PORT]` (1883 by default)."""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import urlsplit

DEFAULT_PORT = 1883


@dataclass(frozen=True)
class BrokerAddress:
    host: str
    port: int = DEFAULT_PORT

    def __str__(self) -> str:
        return f"mqtt://{self.host}:{self.port}"


def parse_broker_url(url: str) -> BrokerAddress:
    """`mqtt://HOST[:PORT]` -> BrokerAddress; ValueError names what is wrong."""
    parts = urlsplit(url.strip())
    if parts.scheme != "mqtt":
        raise ValueError(f"broker {url!r}: expected mqtt://HOST[:PORT] (scheme 'mqtt')")
    if not parts.hostname:
        raise ValueError(f"broker {url!r}: no host (mqtt://HOST[:PORT])")
    if parts.path not in ("", "/") or parts.query:
        raise ValueError(f"broker {url!r}: nothing may follow HOST[:PORT]")
    try:
        port = parts.port or DEFAULT_PORT
    except ValueError:
        raise ValueError(f"broker {url!r}: port must be a number in 1-65535") from None
    return BrokerAddress(parts.hostname, port)
