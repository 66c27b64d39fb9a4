"""wire.frame's helpers for the cyclic exchange's steady state (docs/cards.md, "Performance: the cyclic path"): a
:class:`Template` is packed again only when one of its nine fields changes, and its datagrams are its body with the
cycle and the (R)WDT patched in and sealed, which :func:`steady_delta` reads back."""

from __future__ import annotations

from mlink_sim.wire.frame import CYCLE_AT, FCS_SIZE, Template, cycle_of, fcs_ok, patch_seal, steady_delta

FIELDS = (0x0C, 0x0300_0004, 6000, 120, 0x21, 0x43, 17, 0, 1_000_000)
BODY = bytes(range(44))  # a 32-byte ML-III answer without its FCS (envelope 12 + data 32)
RWDT_AT = 13  # ML-III: the response's RWDT (docs/wire-format.md)


def test_a_template_is_stale_until_it_has_a_body_and_whenever_one_of_its_fields_changes() -> None:
    t = Template(RWDT_AT)
    assert t.stale(*FIELDS) and t.stale(*FIELDS)  # nothing packed yet
    t.body = BODY
    assert not t.stale(*FIELDS)
    for i in range(len(FIELDS)):
        changed = list(FIELDS)
        changed[i] += 1
        assert t.stale(*changed)  # and now kept ...
        assert not t.stale(*changed)
        assert t.stale(*FIELDS)  # ... so the old fields are news again


def test_its_datagrams_carry_the_cycle_and_the_wdt_and_steady_delta_reads_them_back() -> None:
    t = Template(RWDT_AT)
    t.body = BODY
    dg = t.seal(0x1234_5678, 0xA5)
    assert len(dg) == len(BODY) + FCS_SIZE and fcs_ok(dg)
    assert dg[4:8] == (0x1234_5678).to_bytes(4, "little") and dg[RWDT_AT] == 0xA5
    assert CYCLE_AT == 4 and cycle_of(dg) == 0x1234_5678  # the envelope's bytes 4-7 (docs/wire-format.md)
    assert dg[:4] + dg[8:RWDT_AT] + dg[RWDT_AT + 1:-FCS_SIZE] == BODY[:4] + BODY[8:RWDT_AT] + BODY[RWDT_AT + 1:]
    before = t.seal(7, 0x10)
    assert steady_delta(dg, before, 4, RWDT_AT) == 0x1234_5678 | 0xA5 << 32
    assert steady_delta(dg, before, 4, RWDT_AT + 1) == -1  # the WDT byte is not where it was said to be


def test_the_last_datagram_sealed_is_handed_out_again_for_the_same_cycle_wdt_and_body() -> None:
    """A card's answer made ahead and its own answer to that command are sealed from one template: the second is
    the first object again (no copy, no FCS); any other cycle, WDT or body is sealed anew, and every datagram is
    the body with the cycle and the WDT patched in and sealed."""
    t = Template(RWDT_AT)
    t.body = BODY
    first = t.seal(41, 0x21)
    assert t.seal(41, 0x21) is first
    assert first == patch_seal(BODY, CYCLE_AT, 41, RWDT_AT, 0x21)
    for cycle, wdt in ((42, 0x21), (41, 0x22)):
        other = t.seal(cycle, wdt)
        assert other is not first and other == patch_seal(BODY, CYCLE_AT, cycle, RWDT_AT, wdt)
    again = t.seal(41, 0x21)  # only the last one is kept
    assert again is not first and again == first
    t.body = bytes(BODY[:-1]) + b"\xee"  # packed again (a field changed): a new body
    changed = t.seal(41, 0x21)
    assert changed != first and changed == patch_seal(t.body, CYCLE_AT, 41, RWDT_AT, 0x21)
