"""A throwaway PostgreSQL cluster for tests: Debian's `initdb`/`pg_ctl` in a temporary folder,
listening only on a unix socket there (no TCP port), fsync off, removed at the end.

As root (CI containers) the server runs as the `postgres` system user, since PostgreSQL
refuses to run as root; the folder is made its own.
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

PORT = 5432  # only names the socket file (.s.PGSQL.5432) in our folder; no TCP listening


def find_bin_dir() -> Path | None:
    """The newest /usr/lib/postgresql/<version>/bin with initdb and pg_ctl, or None."""
    bins = [Path(p).parent for p in glob.glob("/usr/lib/postgresql/*/bin/initdb")]
    bins = [b for b in bins if b.parent.name.isdigit() and (b / "pg_ctl").exists()]
    return max(bins, key=lambda b: int(b.parent.name)) if bins else None


def why_unavailable() -> str | None:
    """Why no cluster can be started here (None: it can)."""
    if find_bin_dir() is None:
        return (
            "PostgreSQL server binaries not found (/usr/lib/postgresql/*/bin/initdb); "
            "install them with `apt-get install postgresql` (scripts/test.sh does as root)"
        )
    if os.geteuid() == 0:
        try:
            pwd.getpwnam("postgres")
        except KeyError:
            return "running as root and there is no `postgres` user to run the server as"
    return None


class PgCluster:
    """Start with `start()`, get URLs with `url(dbname)`, `create_db`/`drop_db`, `stop()`."""

    def __init__(self) -> None:
        bin_dir = find_bin_dir()
        if bin_dir is None:
            raise RuntimeError(why_unavailable())
        self.bin = bin_dir
        self.root = Path(tempfile.mkdtemp(prefix="irloc-pg-"))
        self.data = self.root / "data"
        self.user = "irloc"
        self._as: dict[str, Any] = {}
        if os.geteuid() == 0:
            pw = pwd.getpwnam("postgres")
            os.chown(self.root, pw.pw_uid, pw.pw_gid)
            self._as = {"user": pw.pw_uid, "group": pw.pw_gid, "extra_groups": []}

    def _run(self, *args: str) -> None:
        subprocess.run(
            [str(self.bin / args[0]), *args[1:]],
            check=True,
            capture_output=True,
            cwd=self.root,
            **self._as,
        )

    def start(self) -> None:
        self._run(
            "initdb", "-D", str(self.data), "-U", self.user, "--auth=trust", "--no-sync",
            "-E", "UTF8", "--locale=C",
        )  # fmt: skip
        opts = f"-k {self.root} -c listen_addresses='' -p {PORT} -c fsync=off"
        self._run("pg_ctl", "-D", str(self.data), "-o", opts, "-l", str(self.root / "log"),
                  "-w", "start")  # fmt: skip

    def url(self, dbname: str) -> str:
        return f"postgresql+psycopg://{self.user}@/{dbname}?host={self.root}&port={PORT}"

    def _admin(self, sql: str) -> None:
        import psycopg

        with psycopg.connect(
            host=str(self.root), port=PORT, user=self.user, dbname="postgres", autocommit=True
        ) as conn:
            conn.execute(sql.encode())

    def create_db(self, name: str, template: str = "template0") -> str:
        """A new database, a copy of `template` (default: empty); returns its URL."""
        self._admin(f'CREATE DATABASE "{name}" TEMPLATE "{template}"')
        return self.url(name)

    def drop_db(self, name: str) -> None:
        self._admin(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')

    def stop(self) -> None:
        try:
            self._run("pg_ctl", "-D", str(self.data), "-m", "immediate", "stop")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)
