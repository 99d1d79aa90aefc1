"""The shipped Mosquitto configuration (deploy/mosquitto/) on Debian's Mosquitto, with test
certificates made by openssl now: no anonymous client, TLS with client certificates,
passwords, and the ACL (an agent writes only its own topics; only the server writes the
map). irloc's clients log in with `mqtts://USER@HOST` and the password from a file."""

from __future__ import annotations

import asyncio
import contextlib
import getpass
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import aiomqtt
import pytest

from fleet.broker import BrokerAddress, parse_broker_url
from fleet.session import make_client
from fleet.topics import SiteTopics
from tests.fleet.mosquitto import free_port, mosquitto_binary

pytestmark = pytest.mark.skipif(
    mosquitto_binary() is None or shutil.which("openssl") is None
    or shutil.which("mosquitto_passwd") is None,
    reason="needs Debian's mosquitto (with mosquitto_passwd) and openssl",
)  # fmt: skip
DEPLOY = Path(__file__).resolve().parents[2] / "deploy" / "mosquitto"
T = SiteTopics("site1")


def openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def make_cert(d: Path, name: str, cn: str, *, san: str | None = None) -> None:
    openssl("req", "-new", "-newkey", "rsa:2048", "-nodes", "-keyout", f"{name}.key",
            "-out", f"{name}.csr", "-subj", f"/CN={cn}", cwd=d)  # fmt: skip
    ext = d / f"{name}.ext"
    ext.write_text(f"subjectAltName={san}\n" if san else "basicConstraints=CA:FALSE\n")
    openssl("x509", "-req", "-in", f"{name}.csr", "-CA", "ca.crt", "-CAkey", "ca.key",
            "-CAcreateserial", "-out", f"{name}.crt", "-days", "2", "-extfile", ext.name,
            cwd=d)  # fmt: skip


@dataclass
class Broker:
    port: int
    dir: Path

    def url(self, user: str | None) -> BrokerAddress:
        who = f"{user}@" if user else ""
        return parse_broker_url(
            f"mqtts://{who}127.0.0.1:{self.port}",
            password_file=self.dir / f"{user}.pw" if user else None,
            ca_file=self.dir / "ca.crt",
            cert_file=self.dir / "client.crt",
            key_file=self.dir / "client.key",
        )


@pytest.fixture(scope="module")
def broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Broker]:
    d = tmp_path_factory.mktemp("locked-broker")
    openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out",
            "ca.crt", "-days", "2", "-subj", "/CN=irloc test CA", cwd=d)  # fmt: skip
    make_cert(d, "broker", "127.0.0.1", san="IP:127.0.0.1")
    make_cert(d, "client", "irloc client")
    passwd = d / "passwd"
    passwd.touch()
    for user in ("irloc-server", "r1", "r2"):
        (d / f"{user}.pw").write_text(f"pw-of-{user}\n")
        subprocess.run(["mosquitto_passwd", "-b", str(passwd), user, f"pw-of-{user}"],
                       check=True, capture_output=True)  # fmt: skip
    shutil.copy(DEPLOY / "acl", d / "acl")
    port = free_port()
    conf = (DEPLOY / "irloc.conf").read_text()
    conf = conf.replace("/etc/mosquitto/irloc/", f"{d}/").replace(
        "listener 8883", f"listener {port} 127.0.0.1"
    )
    conf = conf.replace("persistence true", "persistence false")
    # run as this user (as root, Mosquitto would switch to `mosquitto`: no access to tmp)
    (d / "mosquitto.conf").write_text(conf + f"log_dest stderr\nuser {getpass.getuser()}\n")
    binary = mosquitto_binary()
    assert binary is not None
    proc = subprocess.Popen([binary, "-c", str(d / "mosquitto.conf")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            break
        except OSError:
            time.sleep(0.05)
    try:
        yield Broker(port, d)
    finally:
        proc.terminate()
        proc.wait(5)


async def received(client: aiomqtt.Client, wait_s: float) -> list[tuple[str, bytes]]:
    got: list[tuple[str, bytes]] = []

    async def loop() -> None:
        async for m in client.messages:
            assert isinstance(m.payload, bytes)
            got.append((m.topic.value, m.payload))

    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(loop(), wait_s)
    return got


def test_an_anonymous_or_wrong_password_client_is_refused(broker: Broker) -> None:
    async def attempt(address: BrokerAddress) -> str:
        try:
            async with make_client(address, "intruder"):
                return "connected"
        except aiomqtt.MqttError as exc:
            return str(exc)

    anonymous = asyncio.run(attempt(broker.url(None)))
    assert anonymous != "connected"
    (broker.dir / "bad.pw").write_text("wrong\n")
    wrong = parse_broker_url(
        f"mqtts://r1@127.0.0.1:{broker.port}",
        password_file=broker.dir / "bad.pw",
        ca_file=broker.dir / "ca.crt",
        cert_file=broker.dir / "client.crt",
        key_file=broker.dir / "client.key",
    )
    assert asyncio.run(attempt(wrong)) != "connected"


def test_without_a_client_certificate_tls_is_refused(broker: Broker) -> None:
    address = parse_broker_url(
        f"mqtts://r1@127.0.0.1:{broker.port}",
        password_file=broker.dir / "r1.pw",
        ca_file=broker.dir / "ca.crt",
    )

    async def attempt() -> bool:
        try:
            async with make_client(address, "r1-nocert") as c:
                await c.publish(T.pose("r1"), b"{}")
                return True
        except aiomqtt.MqttError:
            return False

    assert not asyncio.run(attempt())


def test_an_agent_writes_only_its_own_topics_and_only_the_server_writes_the_map(
    broker: Broker,
) -> None:
    async def run() -> tuple[list[tuple[str, bytes]], list[tuple[str, bytes]]]:
        async with (
            make_client(broker.url("irloc-server"), "irloc-server-site1") as server,
            make_client(broker.url("r1"), "r1") as r1,
        ):
            await server.subscribe([(f"{T.root}/#", 1)])
            await r1.subscribe([(T.map, 1), (T.pose("r2"), 1)])
            await asyncio.sleep(0.2)
            await r1.publish(T.pose("r1"), b"r1's own pose", qos=1)
            await r1.publish(T.pose("r2"), b"r1 posing as r2", qos=1)
            await r1.publish(T.map, b"r1's fake map", qos=1, retain=True)
            await r1.publish(T.leds, b"r1's fake LEDs", qos=1, retain=True)
            await r1.publish(T.led_request("r2"), b"r1 asking as r2", qos=1)
            await server.publish(T.map, b"the site's map", qos=1, retain=True)
            server_saw, r1_saw = await asyncio.gather(received(server, 1.0), received(r1, 1.0))
            return server_saw, r1_saw

    server_saw, r1_saw = asyncio.run(run())
    payloads = {p for _, p in server_saw}
    assert b"r1's own pose" in payloads
    assert not payloads & {b"r1 posing as r2", b"r1's fake map", b"r1's fake LEDs",
                           b"r1 asking as r2"}  # fmt: skip
    assert (T.map, b"the site's map") in r1_saw  # the agent reads the site's map
    assert all(t != T.pose("r2") for t, _ in r1_saw)  # not another agent's poses (read denied)


def test_broker_urls_never_show_a_password(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    in_url = parse_broker_url("mqtt://bob:s3cret@host")
    assert in_url.password == "s3cret" and "s3cret" not in f"{in_url} {in_url!r}"
    with pytest.raises(ValueError, match="without a user") as err:
        parse_broker_url("mqtt://:s3cret@host")
    assert "s3cret" not in str(err.value)
    monkeypatch.setenv("IRLOC_MQTT_PASSWORD", "from-env")
    address = parse_broker_url("mqtt://bob@host")
    assert address.password == "from-env" and str(address) == "mqtt://bob@host:1883"
    assert "from-env" not in repr(address)
    (tmp_path / "pw").write_text("from-file\n")
    assert (
        parse_broker_url("mqtt://bob@host", password_file=tmp_path / "pw").password == "from-file"
    )
    assert str(parse_broker_url("mqtts://host")) == "mqtts://host:8883"
    with pytest.raises(ValueError, match="no such file"):
        parse_broker_url("mqtts://host", ca_file=tmp_path / "missing.crt")
    with pytest.raises(ValueError, match="use mqtts"):
        parse_broker_url("mqtt://host", ca_file=tmp_path / "pw")
