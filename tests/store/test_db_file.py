"""The SQLite file: created readable by its user only; an empty, unreadable or foreign file
is refused with a message naming it (never a new site over it, never a traceback)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from server.cli import main as serve_main
from store.db import DatabaseFileError, make_engine, prepare_sqlite_file


def test_a_new_database_is_readable_by_its_user_only(tmp_path: Path) -> None:
    db = tmp_path / "data" / "irloc.db"
    engine = make_engine(f"sqlite:///{db}")
    with engine.connect() as c:
        c.exec_driver_sql("CREATE TABLE t (x)")
    engine.dispose()
    assert db.stat().st_mode & 0o777 == 0o600
    assert (tmp_path / "data").stat().st_mode & 0o777 == 0o700


def test_a_world_readable_database_is_made_private(tmp_path: Path) -> None:
    db = tmp_path / "irloc.db"
    sqlite3.connect(db).execute("CREATE TABLE t (x)").connection.close()
    db.chmod(0o644)
    prepare_sqlite_file(db)
    assert db.stat().st_mode & 0o777 == 0o600


@pytest.mark.parametrize(
    ("content", "said"),
    [
        (b"", r"empty \(0 bytes\)"),
        (b"GIF89a garbage", "not an SQLite database"),
        (None, "cannot be read"),
    ],
)
def test_an_unusable_file_is_refused_naming_it(
    tmp_path: Path, content: bytes | None, said: str
) -> None:
    db = tmp_path / "irloc.db"
    if content is None:
        db.mkdir()  # unreadable as a file (whoever runs the test, root included)
    else:
        db.write_bytes(content)
    with pytest.raises(DatabaseFileError, match=said) as err:
        make_engine(f"sqlite:///{db}")
    assert str(db) in str(err.value)


def test_serve_refuses_an_empty_database_with_a_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "irloc.db").write_bytes(b"")
    assert serve_main(["--data-dir", str(tmp_path), "--no-viewer"]) == 2
    err = capsys.readouterr().err
    assert "empty (0 bytes)" in err and "Traceback" not in err
    assert (tmp_path / "irloc.db").stat().st_size == 0  # untouched: no new site over it
