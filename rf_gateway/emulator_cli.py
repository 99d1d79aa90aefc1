"""Run the emulated XBee coordinator on a pseudo-terminal, to try the XBee path without
hardware: `python -m rf_gateway.emulator_cli /tmp/ttyXBEE --map map.json`, then
`irloc serve --radio xbee:/tmp/ttyXBEE --map map.json`.
"""

from __future__ import annotations

import argparse
import json
import signal
import threading
from pathlib import Path

from rf_gateway.emulator import EmulatedRemote, FaultConfig, XBeeEmulator
from rf_gateway.transport import normalize_address


def remotes_from_map(path: Path) -> list[EmulatedRemote]:
    """One emulated landmark per map.json landmark that has a `radio` address.

    Raises:
        ValueError: naming the file and the landmark with a bad address.
    """
    try:
        doc = json.loads(path.read_text())
        records = doc["landmarks"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not a map.json with a 'landmarks' list ({exc})") from exc
    remotes = []
    for i, rec in enumerate(records):
        if isinstance(rec, dict) and rec.get("radio"):
            source = f"{path}: landmark #{i} (id {rec.get('id')}) radio"
            address = normalize_address(str(rec["radio"]), source=source)
            remotes.append(EmulatedRemote(address, f"LM{rec.get('id', i)}"))
    return remotes


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rf_gateway.emulator_cli", description=__doc__)
    p.add_argument("port", type=Path, help="symlink to create for the pseudo-terminal")
    p.add_argument("--map", type=Path, help="map.json whose landmarks' radios to emulate")
    p.add_argument("--count", type=int, default=0, help="extra landmarks not in any map")
    p.add_argument("--dead", default="", help="comma-separated addresses that never answer")
    p.add_argument("--escaped", action="store_true", help="API mode 2 (AP=2)")
    p.add_argument("--delay-ms", type=float, default=5.0, help="reply latency")
    p.add_argument("--drop", type=float, default=0.0, help="probability a reply is lost")
    p.add_argument(
        "--sleep-ms",
        type=float,
        default=None,
        help="the landmarks sleep in cycles of this period (XBee SP): commands wait for them",
    )
    args = p.parse_args(argv)
    if args.sleep_ms is not None and not 320 <= args.sleep_ms <= 28000:
        p.error(f"--sleep-ms: XBee 3 cyclic sleep periods are 320 .. 28000 ms, got {args.sleep_ms}")
    try:
        remotes = remotes_from_map(args.map) if args.map else []
        dead = {normalize_address(a, source="--dead") for a in args.dead.split(",") if a}
    except ValueError as exc:
        p.error(str(exc))
    remotes += [EmulatedRemote(f"0013A20042{i:06X}", f"NEW{i}") for i in range(1, args.count + 1)]
    for k, remote in enumerate(remotes):
        remote.silent = remote.address in dead
        if args.sleep_ms is not None:  # each radio wakes at its own phase of the cycle
            remote.sleep_period_s = args.sleep_ms / 1e3
            remote.sleep_phase_s = (k * 0.618034 % 1.0) * remote.sleep_period_s
    faults = FaultConfig(delay_s=args.delay_ms / 1e3, drop=args.drop)
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with XBeeEmulator(args.port, remotes, escaped=args.escaped, faults=faults) as emu:
        print(
            f"XBee coordinator emulated at {emu.port} with {len(remotes)} landmarks; Ctrl-C stops"
        )
        stop.wait()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
