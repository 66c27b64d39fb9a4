"""CPU per station exchange on the sans-I/O cores: master encode, card receive, master decode (no sockets).

    python -m benchmarks.micro.exchange [--stations 9] [--cycles 3000]      # from the repository's root

The master core (``mlink_sim.master.MasterCore``) drives SI-T3 (ML-II, 17-byte) or SI-ET3 (ML-III, 32-byte)
card cores in memory on an explicit 1 ms clock; after bring-up and a settling period, each step is timed with
``time.perf_counter_ns()``. Prints µs per station per cycle and one JSON line. docs/performance.md quotes it.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from mlink_sim.cards import create_card, settings_for
from mlink_sim.cli.logs import configure_logging
from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
from mlink_sim.wire import Link

__all__ = ["main", "measure"]

MS = 1_000_000


def measure(link: Link, stations: int, cycles: int) -> dict[str, float]:
    card, size, first = ("si-t3", 17, 0x21) if link is Link.ML2 else ("si-et3", 32, 0x03)
    plan = NetworkPlan(link, MS, tuple(StationPlan(first + i, link, data_size=size) for i in range(stations)))
    slaves = {sp.address: create_card(card, settings=settings_for(card, sp.address, size, []), now=0)
              for sp in plan.stations}
    core = MasterCore(plan)
    source = ("127.0.0.1", 1)
    clock = {"cycle": 0, "now": 0}

    def run(n: int) -> tuple[int, int, int]:
        build = card_ns = parse = 0
        pc = time.perf_counter_ns
        for _ in range(n):
            clock["cycle"] += 1
            clock["now"] += MS
            now = clock["now"]
            t0 = pc()
            out = core.on_cycle(clock["cycle"], now)
            build += pc() - t0
            for address, datagram in out:
                t0 = pc()
                response = slaves[address].receive(datagram, source, now + 10_000)
                card_ns += pc() - t0
                if response:
                    t0 = pc()
                    core.on_response(response, now + 20_000)
                    parse += pc() - t0
            core.drain_events()
            for s in slaves.values():
                s.poll(now + 30_000)
        return build, card_ns, parse

    run(2000)  # bring-up, settle
    build, card_ns, parse = run(cycles)
    states = {v.state.value for v in core.views().values()}
    if states != {"phase3"}:
        raise SystemExit(f"{link.name}: stations not in phase 3: {states}")
    k = cycles * stations
    return {"master_encode_us": round(build / k / 1e3, 2), "card_receive_us": round(card_ns / k / 1e3, 2),
            "master_decode_us": round(parse / k / 1e3, 2)}


def main() -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.micro.exchange", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stations", type=int, default=9)
    ap.add_argument("--cycles", type=int, default=3000)
    args = ap.parse_args()
    if args.stations < 1 or args.cycles < 1:
        print("exchange: --stations and --cycles must be ≥ 1", file=sys.stderr)
        return 2
    configure_logging(level="error")
    out = {}
    for link in (Link.ML2, Link.ML3):
        if link is Link.ML2 and args.stations > 30:
            print(f"ML2: not run: MECHATROLINK-II has at most 30 stations (SI-T3 Table 29), asked {args.stations}")
            continue
        r = out[link.name] = measure(link, args.stations, args.cycles)
        print(f"{link.name}: master encode {r['master_encode_us']} µs, card receive {r['card_receive_us']} µs, "
              f"master decode {r['master_decode_us']} µs  (per station per cycle)")
    print(json.dumps({"stations": args.stations, "cycles": args.cycles, **out}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
