"""`irloc keys`: create, list and revoke API keys in a site's database."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from live.settings import Settings
from store.db import make_engine, migrate
from store.errors import NotFoundError
from store.keys import KeyStore
from store.models import ROLES


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="irloc keys", description="manage API keys")
    p.add_argument("--data-dir", type=Path, help="the site's data folder (default per user)")
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("create", help="create a key and print it (shown only once)")
    c.add_argument("--role", choices=ROLES, required=True)
    c.add_argument("--name", default="")
    c.add_argument("--data-dir", type=Path, dest="data_dir_sub")
    ls = sub.add_parser("list", help="list keys (never the keys themselves)")
    ls.add_argument("--data-dir", type=Path, dest="data_dir_sub")
    r = sub.add_parser("revoke", help="revoke a key by its id")
    r.add_argument("id", type=int)
    r.add_argument("--data-dir", type=Path, dest="data_dir_sub")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    data_dir = getattr(args, "data_dir_sub", None) or args.data_dir
    settings = Settings(data_dir=data_dir) if data_dir else Settings()
    engine = make_engine(settings.db_url)
    migrate(engine)
    keys = KeyStore(engine)
    try:
        if args.command == "create":
            key, record = keys.create(args.role, args.name)
            print(key)
            print(
                f"(key {record.id}, role {record.role}; store it now, it is not shown again)",
                file=sys.stderr,
            )
        elif args.command == "list":
            print("id\trole\tprefix\tstate\tcreated\tlast used (UTC)\tname")
            for k in keys.list():
                state = "revoked" if k.revoked else "active"
                used = "never" if k.last_used_at is None else f"{k.last_used_at:%Y-%m-%d %H:%M}"
                print(
                    f"{k.id}\t{k.role}\t{k.prefix}...\t{state}\t{k.created_at:%Y-%m-%d}\t"
                    f"{used}\t{k.name}"
                )
        else:
            try:
                keys.revoke(args.id)
            except NotFoundError as exc:
                print(f"irloc keys: {exc}", file=sys.stderr)
                return 1
            print(f"key {args.id} revoked")
        return 0
    finally:
        keys.close()
        engine.dispose()
