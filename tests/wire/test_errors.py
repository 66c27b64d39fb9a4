"""Every DropReason from a crafted datagram; decode() never fails with anything but WireError.

Each crafted datagram is wrong in exactly one way: where the defect is not in the FCS, the FCS is recomputed
(:func:`reseal`) so the check under test is the one that fires.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim.wire import DropReason, Frame, Kind, Link, WireError, decode, encode, ml2, ml3
from mlink_sim.wire.fcs import crc16_x25_reference

from wire_strategies import frames

ML2_17 = encode(Frame(Link.ML2, Kind.COMMAND, 0x21, 1, 2_000_000, ml2.M2Command(ml2.PrmRd(0x0200, 2), wdt=1)))
ML2_32 = encode(
    Frame(Link.ML2, Kind.COMMAND, 0x21, 1, 2_000_000, ml2.M2Command(ml2.Nop(), wdt=1, sub=ml2.PrmRd(0x0200, 2)))
)
ML3_32 = encode(Frame(Link.ML3, Kind.RESPONSE, 0x21, 1, 1_000_000, ml3.M3Response(ml3.Nop(), cmd_stat=4)))


def reseal(datagram: bytes) -> bytes:
    """*datagram* with its FCS recomputed (so only the deliberate defect remains)."""
    body = datagram[:-2]
    return body + crc16_x25_reference(body).to_bytes(2, "little")


def patch(datagram: bytes, offset: int, value: int) -> bytes:
    return reseal(datagram[:offset] + bytes([value]) + datagram[offset + 1 :])


def drop(datagram: bytes, **kwargs: object) -> WireError:
    with pytest.raises(WireError) as info:
        decode(datagram, **kwargs)  # type: ignore[arg-type]
    return info.value


# (id, datagram, decode kwargs, expected reason)
CASES = [
    ("empty", b"", {}, DropReason.TOO_SHORT),
    ("too_short_30", ML2_17[:30], {}, DropReason.TOO_SHORT),
    ("envelope_only", reseal(ML2_17[:12] + b"\0\0"), {}, DropReason.TOO_SHORT),
    ("too_long_79", reseal(ML3_32[:-2] + bytes(33) + b"\0\0"), {}, DropReason.TOO_LONG),
    ("bad_magic", patch(ML2_17, 0, 0x4E), {}, DropReason.BAD_MAGIC),
    ("unknown_link_04", patch(ML2_17, 1, 0x04), {}, DropReason.BAD_LINK),
    ("unknown_link_00", patch(ML2_17, 1, 0x00), {}, DropReason.BAD_LINK),
    ("unknown_kind_03", patch(ML2_17, 2, 0x03), {}, DropReason.BAD_KIND),
    ("unknown_kind_00", patch(ML2_17, 2, 0x00), {}, DropReason.BAD_KIND),
    ("32_byte_data_on_ml1", patch(ML2_32, 1, Link.ML1), {}, DropReason.BAD_SIZE),
    ("17_byte_data_on_ml3", patch(ML2_17, 1, Link.ML3), {}, DropReason.BAD_SIZE),
    ("20_byte_data_on_ml3", reseal(ML3_32[:12] + bytes(20) + b"\0\0"), {}, DropReason.BAD_SIZE),
    ("data_size_mismatch", ML2_17, {"data_size": 32}, DropReason.BAD_SIZE),
    ("data_size_mismatch_ml3", ML3_32, {"data_size": 64}, DropReason.BAD_SIZE),
    ("bad_fcs_one_bit", ML2_17[:-2] + bytes([ML2_17[-2] ^ 0x01, ML2_17[-1]]), {}, DropReason.BAD_FCS),
    ("bad_fcs_data_bit", ML2_17[:20] + bytes([ML2_17[20] ^ 0x80]) + ML2_17[21:], {}, DropReason.BAD_FCS),
    ("wrong_kind_command_to_master", ML2_17, {"kind": Kind.RESPONSE}, DropReason.WRONG_KIND),
    ("wrong_kind_response_to_slave", ML3_32, {"kind": Kind.COMMAND}, DropReason.WRONG_KIND),
]


@pytest.mark.parametrize(("datagram", "kwargs", "reason"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_drop_reason(datagram: bytes, kwargs: dict[str, object], reason: DropReason) -> None:
    err = drop(datagram, **kwargs)
    assert err.reason is reason
    msg = str(err)
    assert msg and "\n" not in msg  # one line
    assert msg.startswith(f"{reason.value}: ")
    assert err.detail and err.detail in msg


def test_every_drop_reason_is_produced() -> None:
    assert {c[3] for c in CASES} == set(DropReason)


def test_wire_error_is_a_value_error() -> None:
    assert issubclass(WireError, ValueError)


def test_valid_crafting_bases_decode() -> None:
    """The bases the cases are crafted from are themselves valid (so each case has exactly one defect)."""
    for dg in (ML2_17, ML2_32, ML3_32):
        decode(dg)
    decode(ML2_17, data_size=17, kind=Kind.COMMAND)
    decode(ML3_32, data_size=32, kind=Kind.RESPONSE)


@pytest.mark.parametrize("base", [ML2_17, ML2_32, ML3_32], ids=["ml2-17", "ml2-32", "ml3-32"])
def test_every_single_bit_flip_after_the_magic_is_a_bad_fcs(base: bytes) -> None:
    """CRC-16 detects every single-bit error: flip each bit of link, kind, station, cycle, tcycle, data and FCS.
    The FCS is checked before the header fields it protects, so a corrupted link byte is a bad FCS too."""
    for offset in range(1, len(base)):
        for bit in range(8):
            dg = bytearray(base)
            dg[offset] ^= 1 << bit
            assert drop(bytes(dg)).reason is DropReason.BAD_FCS, (offset, bit)


def test_fcs_is_checked_before_the_size() -> None:
    # a 32-byte data area on ML-I with a *bad* FCS is a transmission error first
    dg = bytearray(patch(ML2_32, 1, Link.ML1))
    dg[-1] ^= 0xFF
    assert drop(bytes(dg)).reason is DropReason.BAD_FCS


def test_decode_accepts_memoryview_and_bytearray() -> None:
    assert decode(memoryview(ML2_17)) == decode(bytearray(ML2_17)) == decode(ML2_17)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=100))
def test_decode_arbitrary_bytes_returns_frame_or_wire_error(data: bytes) -> None:
    try:
        frame = decode(data)
    except WireError as err:
        assert isinstance(err.reason, DropReason)
        assert "\n" not in str(err)
    else:
        assert isinstance(frame, Frame)


@st.composite
def near_valid(draw: st.DrawFn) -> bytes:
    """A valid datagram with a few bytes changed, truncated or extended – sometimes resealed."""
    dg = bytearray(encode(draw(frames())))
    for _ in range(draw(st.integers(0, 3))):
        i = draw(st.integers(0, len(dg) - 1))
        dg[i] = draw(st.integers(0, 255))
    cut = draw(st.integers(-3, 3))
    dg = dg[:cut] if cut < 0 else dg + bytes(cut)
    out = bytes(dg)
    return reseal(out) if draw(st.booleans()) and len(out) >= 2 else out


@settings(max_examples=150, deadline=None)
@given(near_valid(), st.sampled_from([None, 17, 32, 64]), st.sampled_from([None, Kind.COMMAND, Kind.RESPONSE]))
def test_decode_near_valid_returns_frame_or_wire_error(data: bytes, data_size: int | None, kind: Kind | None) -> None:
    try:
        frame = decode(data, data_size=data_size, kind=kind)
    except WireError as err:
        assert isinstance(err.reason, DropReason)
        assert "\n" not in str(err)
    else:
        assert isinstance(frame, Frame)
        assert data_size is None or frame.data_size == data_size
        assert kind is None or frame.kind is kind
