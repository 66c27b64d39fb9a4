"""The per-cycle INV_CTL fast path answers byte for byte like the general path (frames through mlink_sim.wire)."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim.cards.base import SLOW
from mlink_sim.wire import CommAlm, Kind, M2Alarm, decode, encode, ml2, ml3
from mlink_sim.wire.frame import with_fcs

from .helpers import MS, Master, alarm, comm_alm, station

PARAMS = {"si-t3": ("b1-01=3", "b1-02=3"), "si-et3": ("b1-01=3", "b1-02=3"), "si-t-v7": ("n003=3", "n004=9")}

u16 = st.integers(0, 0xFFFF)
s16 = st.integers(-0x8000, 0x7FFF)
step = st.fixed_dictionaries({
    "signals": st.sampled_from([0, 1, 2, 3, 0x100, 0x200, 0x8000, 0x4000, 0x3C]) | u16,
    "speed": st.sampled_from([0, 3000, 6000]) | u16,
    "torque": s16,
    "sel_ref": st.integers(0, 0xFF),
    "sel_mon": st.integers(0, 0xFF),
    "refs": st.tuples(u16, u16),
    "skip": st.sampled_from([0, 0, 0, 0, 1, 2]),
    "wdt_bad": st.sampled_from([False] * 9 + [True]),
    "ctrl": st.sampled_from([0, 0, 0x08, 0x40, 0x80, 0xC8]),
    "sub": st.sampled_from(["nop", "nop", "nop", "prm_rd"]),
})


def _pair(card: str, size: int | None) -> tuple[Master, Master]:
    fast = Master(station(card, params=PARAMS[card], frame_size=size))
    slow = Master(station(card, params=PARAMS[card], frame_size=size))
    slow.st._fast_receive = lambda *a: SLOW  # type: ignore[method-assign]
    for m in (fast, slow):
        m.bring_up()
    return fast, slow


@pytest.mark.parametrize("card, size", [("si-t3", 32), ("si-t3", 17), ("si-t-v7", 32), ("si-t-v7", 17),
                                        ("si-et3", 64), ("si-et3", 32)])
@settings(max_examples=60, deadline=None)
@given(steps=st.lists(step, min_size=1, max_size=40))
def test_fast_path_matches_the_general_path(card: str, size: int, steps: list[dict]) -> None:
    fast, slow = _pair(card, size)
    for s in steps:
        for m in (fast, slow):
            m.tick(s["skip"] + 1)
        if fast.ml3:
            body = ml3.InvCtl(s["signals"] | (s["signals"] << 8 & 0xFF0000), 0, s["speed"], s["torque"], s["sel_ref"],
                              s["sel_mon"], *s["refs"])
            sub = ml3.PrmRd(0x0200, 2) if s["sub"] == "prm_rd" and size == 64 else None
            kw = {"cmd_ctrl": s["ctrl"]}
        else:
            body = ml2.InvCtl(s["signals"], s["speed"], s["torque"], s["sel_ref"], s["sel_mon"], *s["refs"])
            sub = ml2.PrmRd(0x0200, 2) if s["sub"] == "prm_rd" and size == 32 else None
            kw = {}
        wdt = 0x05 if s["wdt_bad"] else None
        raw = [m.st.receive(encode(m.command(body, sub, wdt=wdt, **kw)), m.source, m.now) for m in (fast, slow)]
        assert raw[0] == raw[1]
    assert fast.st.counters.as_dict() == slow.st.counters.as_dict()
    assert fast.st.snapshot().drive == slow.st.snapshot().drive


def test_fast_path_taken() -> None:
    m = Master(station("si-t3", params=PARAMS["si-t3"]))
    m.bring_up()
    calls = []
    real = m.st._process
    m.st._process = lambda *a: calls.append(1) or real(*a)  # type: ignore[method-assign]
    m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    assert calls == [] and m.last is not None
    m.st.poll(m.now + 100 * MS)


def _inv_ctl(ml3_link: bool, signals: int, speed: int, sel_mon: int) -> Any:
    if ml3_link:
        return ml3.InvCtl(signals, 0, speed, 0, 0, sel_mon, 0, 0)
    return ml2.InvCtl(signals, speed, 0, 0, sel_mon, 0, 0)


@pytest.mark.parametrize("card, size", [("si-t3", 17), ("si-t-v7", 17), ("si-et3", 32)])
def test_kept_outputs_equal_fresh_ones_table18_table22(card: str, size: int) -> None:
    """While the drive is steady the INV_CTL outputs are kept (Station._outputs); they must equal values computed
    every cycle through ramps, steady running, every SEL_MON code (SI-T3 Table 18, SI-ET3 Table 22, SI-T/V7
    Table 5), an external fault (EF0) and its reset, and a fault-history clear."""
    kept = Master(station(card, params=PARAMS[card], frame_size=size))
    fresh = Master(station(card, params=PARAMS[card], frame_size=size))
    fresh.st.keep_outputs = False
    for m in (kept, fresh):
        m.bring_up()
    ml3_link = kept.ml3
    fwd, ef0, reset, hist_clear = (1, 0x400, 0x200, 0x800) if ml3_link else (1, 0x100, 0x200, 0x4000)
    plan = [(fwd, 1000, 0x21, 3000)]                                    # accelerate (C1-01), run steady
    plan += [(fwd, 1000, code | code << 4, 50) for code in range(16)]   # every SEL_MON code while steady
    plan += [(fwd, 6000, 0x21, 1500), (fwd | ef0, 6000, 0x21, 300), (0, 0, 0x21, 300), (reset, 0, 0x21, 5),
             (0, 0, 0x21, 300), (hist_clear, 0, 0x21, 5), (0, 0, 0x98, 200)]
    hits = 0
    for signals, speed, sel_mon, cycles in plan:
        body = _inv_ctl(ml3_link, signals, speed, sel_mon)
        for _ in range(cycles):
            for m in (kept, fresh):
                m.tick()
            raw = [m.st.receive(encode(m.command(body)), m.source, m.now) for m in (kept, fresh)]
            assert raw[0] == raw[1] and raw[0] is not None
            hits += kept.st._out_key >= 0
            for m in (kept, fresh):
                m.slave_echo = decode(raw[0], kind=Kind.RESPONSE).message.rwdt & 0xF
    assert hits > 2000  # the kept values were used


@pytest.mark.parametrize("card, size", [("si-t3", 32), ("si-t3", 17), ("si-t-v7", 32), ("si-t-v7", 17),
                                        ("si-et3", 64), ("si-et3", 32)])
def test_the_steady_state_matches_the_general_path(card: str, size: int) -> None:
    """The fast path's steady state (a command that differs from the last one only in its cycle, WDT and FCS is not
    unpacked again; the answer is the last one's template with its cycle and RWDT patched in): byte for byte the
    general path's answers over long runs of one command while the drive ramps and its outputs move, a corrupted
    FCS on an otherwise identical command (the general path's drop, SI-T3 Table 22 / SI-ET3 COMM_ALM), a wrong
    WDT, skipped cycles, an ALM_CLR edge (ML-III), another station's byte and a command that changes again."""
    fast, slow = _pair(card, size)
    ml3_link = fast.ml3
    fwd = 1
    plan: list[tuple[int, int, int, str]] = [(fwd, 3000, 0x21, "run")] * 400 + [(fwd, 3000, 0x21, "bad_fcs")]
    plan += [(fwd, 3000, 0x21, "run")] * 5 + [(fwd, 3000, 0x21, "bad_wdt")] + [(fwd, 3000, 0x21, "run")] * 5
    plan += [(fwd, 3000, 0x21, "skip")] + [(fwd, 3000, 0x21, "run")] * 5 + [(fwd, 3000, 0x21, "station")]
    plan += [(fwd, 3000, 0x21, "clear")] + [(fwd, 3000, 0x21, "run")] * 5
    plan += [(fwd, 6000, 0x43, "run")] * 300 + [(0, 0, 0x43, "run")] * 300
    for signals, speed, sel_mon, what in plan:
        body = _inv_ctl(ml3_link, signals, speed, sel_mon)
        for m in (fast, slow):
            m.tick(2 if what == "skip" else 1)
        kw: dict[str, Any] = {"cmd_ctrl": 0x08} if what == "clear" and ml3_link else {}
        if what == "bad_wdt":
            kw["wdt"] = 0x05
        datagrams = [bytearray(encode(m.command(body, **kw))) for m in (fast, slow)]
        for dg in datagrams:
            if what == "bad_fcs":
                dg[-1] ^= 0x10
            elif what == "station":
                dg[3] ^= 0x01
                dg[-2:] = with_fcs(bytes(dg[:-2]))[-2:]
        raw = [m.st.receive(bytes(dg), m.source, m.now) for m, dg in zip((fast, slow), datagrams)]
        assert raw[0] == raw[1], what
        if raw[0] is not None:
            for m in (fast, slow):
                m.slave_echo = decode(raw[0], kind=Kind.RESPONSE).message.rwdt & 0xF
    assert fast.st.counters.as_dict() == slow.st.counters.as_dict()
    counts = fast.st.counters.as_dict()
    assert counts["dropped_by_reason"].get("BAD_FCS") == 1 and counts["other_station"] == 1
    assert counts["wdt_errors"] == 1 and counts["rx_ok"] == len(plan) - 2 + 2  # and CONNECT, SYNC_SET
    assert fast.st.snapshot().drive == slow.st.snapshot().drive


@pytest.mark.parametrize("card, size", [("si-t3", 17), ("si-t-v7", 32), ("si-et3", 32), ("si-et3", 64)])
def test_a_new_transmission_cycle_after_a_steady_run_is_a_cycle_fault(card: str, size: int) -> None:
    """After a steady run, a command whose only news besides its cycle and WDT is the header's transmission cycle
    (bytes 8–11) is not the steady state: it is a transmission cycle fault, E6 on MECHATROLINK-II (SI-T3 Table 22,
    SI-T/V7 Table 7) and COMM_ALM B, synchronization interval error, on the SI-ET3; the fast and the general card
    answer alike."""
    fast, slow = _pair(card, size)
    body = _inv_ctl(fast.ml3, 1, 3000, 0x21)
    for cycle in range(51):
        for m in (fast, slow):
            m.tick()
        other = {"tcycle_ns": 2 * MS} if cycle == 50 else {}
        raw = [m.st.receive(encode(m.command(body, **other)), m.source, m.now) for m in (fast, slow)]
        assert raw[0] == raw[1] and raw[0] is not None
        answer = decode(raw[0], kind=Kind.RESPONSE)
        for m in (fast, slow):
            m.slave_echo = answer.message.rwdt & 0xF
    if fast.ml3:
        assert comm_alm(answer) == CommAlm.SYNC_INTERVAL_ERROR
    else:
        assert alarm(answer) == M2Alarm.COMM_ERROR == 0xE6
    assert fast.st.counters.as_dict() == slow.st.counters.as_dict()
