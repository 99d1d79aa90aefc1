"""RF gateway benchmark: commands per second, latency (p50, p99) and the time from
"light only landmark k" to the confirmed LedsChanged event, through the XBee emulator (digi-xbee
over a pseudo-terminal) and through the simulated radio of the virtual site.

Run: .venv/bin/python bench/bench_rf.py [--commands 400] [--sweeps 40] [--landmarks 8]
"""

from __future__ import annotations

import argparse
import asyncio
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lighting.battery import Battery
from rf_gateway import Gateway, GatewayConfig
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.emulator import EmulatedRemote, FaultConfig, XBeeEmulator
from rf_gateway.sim_transport import SimTransport
from rf_gateway.transport import Transport
from rf_gateway.xbee_transport import XBeeTransport, XBeeTransportConfig
from sim.radio import SimRadio
from sim.world import SimLandmark, World


@dataclass(frozen=True)
class Row:
    name: str
    count: int
    per_s: float
    p50_ms: float
    p99_ms: float


def row(name: str, latencies_s: list[float], wall_s: float) -> Row:
    lat = np.asarray(latencies_s) * 1e3
    return Row(
        name,
        len(lat),
        len(lat) / wall_s,
        float(np.percentile(lat, 50)),
        float(np.percentile(lat, 99)),
    )


async def bench_commands(
    transport: Transport, addresses: list[str], n: int, concurrency: int
) -> tuple[list[float], float]:
    """`n` set_pin commands, `concurrency` at a time; per-command latencies and wall time."""
    latencies: list[float] = []
    counter = iter(range(n))

    async def worker() -> None:
        for i in counter:
            t0 = time.perf_counter()
            await transport.set_pin(addresses[i % len(addresses)], bool(i // len(addresses) % 2))
            latencies.append(time.perf_counter() - t0)

    t0 = time.perf_counter()
    await asyncio.gather(*(worker() for _ in range(concurrency)))
    return latencies, time.perf_counter() - t0


async def bench_light_only(gw: Gateway, sweeps: int) -> tuple[list[float], float]:
    """Time from set_leds([k]) to the subscriber receiving the confirmed event."""
    ids = sorted(gw.landmarks)
    sub = gw.subscribe()
    latencies: list[float] = []
    t_start = time.perf_counter()
    for s in range(sweeps):
        await gw.set_leds(ids)  # back to all lit (not timed)
        while sub.get_nowait() is not None:
            pass
        k = ids[s % len(ids)]
        t0 = time.perf_counter()
        task = asyncio.create_task(gw.set_leds([k]))
        event = await sub.next()
        latencies.append(time.perf_counter() - t0)
        await task
        if event.lit != frozenset({k}):
            raise RuntimeError(f"sweep {s}: expected only {k} lit, got {event}")
    return latencies, time.perf_counter() - t_start


GW_CONFIG = GatewayConfig(
    battery=BatteryMonitorConfig(interval_s=None), max_tries=5, light_all_on_start=False
)


async def run_xbee(args: argparse.Namespace, tmp: Path, pipelined: bool) -> list[Row]:
    addresses = [f"0013A20040B000{i:02X}" for i in range(1, args.landmarks + 1)]
    remotes = [EmulatedRemote(a, f"LM{i}") for i, a in enumerate(addresses, 1)]
    faults = FaultConfig(delay_s=args.xbee_delay_ms / 1e3)
    kind = "xbee pipelined" if pipelined else "xbee emulator"
    with XBeeEmulator(tmp / "ttyBENCH", remotes, faults=faults):
        config = XBeeTransportConfig(pipelined=pipelined)
        transport = XBeeTransport(str(tmp / "ttyBENCH"), config=config)
        gw = Gateway(transport, dict(enumerate(addresses, 1)), GW_CONFIG)
        await gw.start()
        rows = []
        for concurrency in (1, 4):
            lat, wall = await bench_commands(transport, addresses, args.commands // 2, concurrency)
            name = f"{kind}: set_pin x{concurrency} ({args.xbee_delay_ms:g} ms radio)"
            rows.append(row(name, lat, wall))
        lat, wall = await bench_light_only(gw, args.sweeps)
        rows.append(row(f"{kind}: light only k -> event", lat, wall))
        await gw.close()
    return rows


async def run_sim(args: argparse.Namespace) -> list[Row]:
    addresses = [f"0013A20041C000{i:02X}" for i in range(1, args.landmarks + 1)]
    world = World(
        {
            i: SimLandmark(i, np.array([i, 0.0, 2.5]), np.array([i, 0.0, 2.5]), a, Battery())
            for i, a in enumerate(addresses, 1)
        }
    )
    radio = SimRadio(world, rng=np.random.default_rng(0), loss=args.sim_loss)
    transport = SimTransport(radio)
    gw = Gateway(transport, dict(enumerate(addresses, 1)), GW_CONFIG)
    await gw.start()
    rows = []
    for concurrency in (1, 4):
        lat, wall = await bench_commands(transport, addresses, args.commands // 4, concurrency)
        lost = f", loss {args.sim_loss:g}" if args.sim_loss else ""
        rows.append(row(f"sim radio: set_pin x{concurrency} in flight{lost}", lat, wall))
    lat, wall = await bench_light_only(gw, args.sweeps)
    rows.append(row("sim radio: light only k -> event", lat, wall))
    await gw.close()
    return rows


def print_table(rows: list[Row]) -> None:
    header = f"{'measure':<48} {'n':>5} {'per s':>8} {'p50 ms':>8} {'p99 ms':>8}"
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{r.name:<48} {r.count:>5} {r.per_s:>8.1f} {r.p50_ms:>8.2f} {r.p99_ms:>8.2f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commands", type=int, default=400)
    parser.add_argument("--sweeps", type=int, default=40)
    parser.add_argument("--landmarks", type=int, default=8)
    parser.add_argument("--xbee-delay-ms", type=float, default=2.0)
    parser.add_argument("--sim-loss", type=float, default=0.0)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rows = asyncio.run(run_xbee(args, Path(tmp), pipelined=False))
        rows += asyncio.run(run_xbee(args, Path(tmp), pipelined=True))
        rows += asyncio.run(run_sim(args))
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
