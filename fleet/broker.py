"""Where the broker is and how to log in: `mqtt://[USER@]HOST[:PORT]` (1883 by default) or
`mqtts://[USER@]HOST[:PORT]` (TLS, 8883 by default).

The password comes from a file (`password_file`) or the environment
(`IRLOC_MQTT_PASSWORD`); one in the URL (`mqtt://USER:PASSWORD@HOST`) is used too, but a URL
ends up in shell history and process lists: prefer the file. TLS
verifies the broker against `ca_file` (the system's CAs when not given) and presents a
client certificate when `cert_file` (and `key_file`) are given. `str()` of an address
shows the user, never the password.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlsplit

DEFAULT_PORT = 1883
DEFAULT_TLS_PORT = 8883
PASSWORD_ENV = "IRLOC_MQTT_PASSWORD"


@dataclass(frozen=True)
class BrokerTls:
    """TLS files: the CA that signed the broker's certificate, and this client's own."""

    ca_file: Path | None = None
    cert_file: Path | None = None
    key_file: Path | None = None


@dataclass(frozen=True)
class BrokerAddress:
    host: str
    port: int = DEFAULT_PORT
    username: str | None = None
    password: str | None = field(default=None, repr=False)
    tls: BrokerTls | None = None

    def __str__(self) -> str:
        scheme = "mqtts" if self.tls is not None else "mqtt"
        user = f"{self.username}@" if self.username else ""
        return f"{scheme}://{user}{self.host}:{self.port}"


def read_password(password_file: Path | str | None) -> str | None:
    """The broker password: the first line of `password_file`, else `$IRLOC_MQTT_PASSWORD`,
    else None. ValueError names an unreadable or empty file."""
    if password_file:
        path = Path(password_file)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ValueError(f"broker password file {path}: {exc.strerror or exc}") from None
        line = text.splitlines()[0].strip() if text.strip() else ""
        if not line:
            raise ValueError(f"broker password file {path}: empty")
        return line
    return os.environ.get(PASSWORD_ENV) or None


def _tls_files(
    ca_file: Path | str | None, cert_file: Path | str | None, key_file: Path | str | None
) -> BrokerTls:
    files = {"CA": ca_file, "certificate": cert_file, "key": key_file}
    for what, value in files.items():
        if value and not Path(value).is_file():
            raise ValueError(f"broker TLS {what} file {value}: no such file")
    if key_file and not cert_file:
        raise ValueError("broker TLS: a key file needs its certificate file (cert_file)")
    return BrokerTls(
        Path(ca_file) if ca_file else None,
        Path(cert_file) if cert_file else None,
        Path(key_file) if key_file else None,
    )


def parse_broker_url(
    url: str,
    *,
    password_file: Path | str | None = None,
    ca_file: Path | str | None = None,
    cert_file: Path | str | None = None,
    key_file: Path | str | None = None,
) -> BrokerAddress:
    """`mqtt[s]://[USER@]HOST[:PORT]` and the login files -> BrokerAddress; ValueError names
    what is wrong (never repeating a password)."""
    parts = urlsplit(url.strip())
    shown = f"{parts.scheme}://{parts.hostname or ''}" if parts.password else url
    if parts.scheme not in ("mqtt", "mqtts"):
        raise ValueError(
            f"broker {shown!r}: expected mqtt://[USER@]HOST[:PORT] or mqtts://... "
            "(TLS; scheme 'mqtt' or 'mqtts')"
        )
    if not parts.hostname:
        raise ValueError(f"broker {url!r}: no host (mqtt://HOST[:PORT])")
    if parts.path not in ("", "/") or parts.query:
        raise ValueError(f"broker {url!r}: nothing may follow HOST[:PORT]")
    tls = parts.scheme == "mqtts"
    if not tls and (ca_file or cert_file or key_file):
        raise ValueError(f"broker {url!r}: TLS files given for plain mqtt://; use mqtts://")
    try:
        port = parts.port or (DEFAULT_TLS_PORT if tls else DEFAULT_PORT)
    except ValueError:
        raise ValueError(f"broker {url!r}: port must be a number in 1-65535") from None
    username = unquote(parts.username) if parts.username else None
    if parts.password is not None and not username:
        raise ValueError(f"broker {shown!r}: a password without a user name")
    in_url = unquote(parts.password) if parts.password is not None else None
    password = (in_url or read_password(password_file)) if username else None
    return BrokerAddress(
        parts.hostname,
        port,
        username=username,
        password=password,
        tls=_tls_files(ca_file, cert_file, key_file) if tls else None,
    )
