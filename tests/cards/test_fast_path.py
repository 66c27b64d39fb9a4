"""The per-cycle INV_CTL fast path answers byte for byte like the general path (frames through mlink_sim.wire)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim.cards.base import SLOW
from mlink_sim.wire import encode, ml2, ml3

from .helpers import MS, Master, station

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
