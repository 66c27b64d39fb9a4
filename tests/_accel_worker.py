"""One side of the compiled-vs-pure equivalence tests (tests/test_accel.py): run as a subprocess, with
``MLINK_PURE=1`` (the pure-Python cores) or ``MLINK_PURE=0`` (the compiled ones), it reads one JSON request a line
on stdin and writes one JSON answer a line: everything the cores produced, floats as ``repr`` (exact), bytes as
hex. The test sends the same request to both sides and compares the answers byte for byte.

Cases: ``drive`` (a drive model stepped through commands and times), ``exchange`` (a master core and its cards
over a lossy, corrupting in-memory line), ``datagram`` (one datagram into a card in phase 3 and into the master:
the response bytes, the decode result, the counters).
"""

from __future__ import annotations

import hashlib
import json
import random
import sys
from typing import Any

from mlink_sim import _accel
from mlink_sim.cards import create_card, settings_for
from mlink_sim.drive import Drive, DriveCommand, DriveSettings, Family, LoadSpec
from mlink_sim.master import MasterCore, NetworkPlan, StationPlan
from mlink_sim.wire import Link, WireError, decode

MS = 1_000_000
#: the integrator's state (mlink_sim.drive.integrate.IntegratorState): compared exactly, float by float
_STATE = ("m", "q", "dir", "out", "fout", "w", "T", "I", "P", "E", "V", "theta", "hold_acc", "hold_dec",
          "tlimited", "steady", "ss", "ss_f")
#: card name -> (link, data size, first address)
CARDS = {"si-t3": (Link.ML2, 17, 0x21), "si-t-v7": (Link.ML2, 32, 0x21), "si-et3": (Link.ML3, 32, 0x03)}


def drive(req: dict[str, Any]) -> list[str]:
    kind, inertia, torque, viscous = req["load"]
    family = Family(req["family"])
    settings = DriveSettings.from_defaults(family, {"b1-01": 3, "b1-02": 3, **req["params"]})
    d = Drive(family, settings, LoadSpec(kind, inertia, torque, viscous))
    now, out = 0, []
    for dt, fwd, rev, ref, ebb, reset, tref, tlim in req["steps"]:
        now += dt
        d.command(DriveCommand(forward=fwd, reverse=rev, freq_ref_raw=ref, external_baseblock=ebb,
                               fault_reset=reset, torque_ref_raw=tref, torque_limit_raw=tlim), now)
        d.advance(now)
        st = d.status
        x = d._x
        out.append(repr((now, st, d.output_frequency_hz, d.output_current_a, d.is_steady,
                         d.sel_mon("SI-T3", 1), d.sel_mon("SI-T3", 6), tuple(getattr(x, n) for n in _STATE))))
    return out


def exchange(req: dict[str, Any]) -> dict[str, Any]:
    """Master core and cards for ``cycles`` cycles; each datagram is lost with ``loss`` or gets one bit flipped
    with ``flip`` (seeded); the control changes at the cycles in ``controls``."""
    card = req["card"]
    link, size, first = CARDS[card]
    plan = NetworkPlan(link, MS, tuple(StationPlan(first + i, link, data_size=size)
                                       for i in range(req["stations"])))
    slaves = {sp.address: create_card(card, settings=settings_for(card, sp.address, size, []), now=0)
              for sp in plan.stations}
    core = MasterCore(plan)
    rng = random.Random(req["seed"])
    digest = hashlib.sha256()
    controls = {c[0]: c[1:] for c in req["controls"]}
    events: list[str] = []

    def line(dg: bytes) -> bytes | None:
        if rng.random() < req["loss"]:
            return None
        if rng.random() < req["flip"]:
            bit = rng.randrange(len(dg) * 8)
            dg = bytes(b ^ (1 << (bit & 7)) if i == bit >> 3 else b for i, b in enumerate(dg))
        return dg

    for cycle in range(1, req["cycles"] + 1):
        now = cycle * MS
        if cycle in controls:
            fwd, ref = controls[cycle]
            for address in slaves:
                core.set_control(address, forward=fwd, speed_ref=ref)
        for address, dg in core.on_cycle(cycle, now):
            digest.update(dg)
            got = line(dg)
            response = slaves[address].receive(got, ("127.0.0.1", 1), now + 10_000) if got is not None else None
            if response:
                digest.update(response)
                back = line(response)
                if back is not None:
                    core.on_response(back, now + 20_000)
        events.extend(repr(e) for e in core.drain_events())
        for s in slaves.values():
            s.poll(now + 30_000)
    return {"digest": digest.hexdigest(), "events": events,
            "views": repr(sorted(core.views().items())),
            "snapshots": [repr(s.snapshot()) for s in slaves.values()]}


def datagram(req: dict[str, Any]) -> dict[str, Any]:
    """A card brought to phase 3 over a clean line, then ``data`` into it and into the master."""
    card = req["card"]
    link, size, first = CARDS[card]
    plan = NetworkPlan(link, MS, (StationPlan(first, link, data_size=size),))
    slave = create_card(card, settings=settings_for(card, first, size, []), now=0)
    core = MasterCore(plan)
    now = 0
    for cycle in range(1, 200):
        now = cycle * MS
        for _, dg in core.on_cycle(cycle, now):
            response = slave.receive(dg, ("127.0.0.1", 1), now + 10_000)
            if response:
                core.on_response(response, now + 20_000)
        slave.poll(now + 30_000)
    data = bytes.fromhex(req["data"])
    response = slave.receive(data, ("127.0.0.1", 1), now + MS)
    core.on_response(data, now + MS)
    try:
        decoded = repr(decode(data))
    except WireError as exc:
        decoded = f"WireError: {exc}"
    return {"response": response.hex() if response else None, "decoded": decoded,
            "card": repr(slave.snapshot()), "events": [repr(e) for e in core.drain_events()],
            "views": repr(sorted(core.views().items()))}


CASES = {"drive": drive, "exchange": exchange, "datagram": datagram}


def main() -> int:
    print(json.dumps({"mode": _accel.MODE, "reason": _accel.REASON}), flush=True)
    for raw in sys.stdin:
        req = json.loads(raw)
        try:
            answer: Any = CASES[req["case"]](req)
        except Exception as exc:  # noqa: BLE001  # an exception is an answer too: both sides must raise the same
            answer = {"exception": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
