"""`irloc keys` and the argument checks of `irloc serve`."""

from __future__ import annotations

from pathlib import Path

import pytest

from server import cli, keys_cli
from server.loopback import is_loopback
from store import KeyStore
from store.db import make_engine


def test_keys_create_list_revoke(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert (
        keys_cli.main(
            ["create", "--role", "operator", "--name", "ops", "--data-dir", str(tmp_path)]
        )
        == 0
    )
    key = capsys.readouterr().out.strip()
    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    found = KeyStore(engine).role_of(key)
    assert found is not None and found[1] == "operator"
    assert keys_cli.main(["list", "--data-dir", str(tmp_path)]) == 0
    listing = capsys.readouterr().out
    assert "operator" in listing and "ops" in listing and key not in listing
    assert keys_cli.main(["revoke", str(found[0]), "--data-dir", str(tmp_path)]) == 0
    assert KeyStore(engine).role_of(key) is None
    assert keys_cli.main(["revoke", "99", "--data-dir", str(tmp_path)]) == 1
    engine.dispose()


def test_keys_refuse_an_unknown_role(tmp_path: Path) -> None:
    with pytest.raises(SystemExit):
        keys_cli.main(["create", "--role", "root", "--data-dir", str(tmp_path)])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--radio", "zigbee"], "radio"),
        (["--map", "/nonexistent/map.json"], "no such file"),
        (["--port", "70000"], "port"),
    ],
)
def test_serve_refuses_bad_options(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert cli.main(["--data-dir", str(tmp_path), *args]) == 2
    assert message in capsys.readouterr().err


def test_loopback_check() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1")
    assert is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
