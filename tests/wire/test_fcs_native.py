"""The FCS's C module (mlink_sim/wire/_fcsc.c) against the pure-Python functions, byte for byte.

The module is loaded from its file, so both passes of scripts/test (compiled and ``MLINK_PURE=1``) run these
tests. Without a compiled build they are skipped, unless ``MLINK_REQUIRE_COMPILED=1`` (scripts/test sets it when
the build compiled). docs/wire-format.md "Frame check sequence".
"""

from __future__ import annotations

import importlib.util
import os
import struct
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim import _accel
from mlink_sim.wire import frame
from mlink_sim.wire.fcs import crc16_x25_pure, crc16_x25_reference

ROOT = Path(__file__).resolve().parents[2]
NAME = "mlink_sim.wire._fcsc"


def _load() -> ModuleType:
    path = _accel._extension(NAME)
    if path is None:
        if os.environ.get("MLINK_REQUIRE_COMPILED", "") not in ("", "0"):
            pytest.fail(f"{NAME} is not built, and MLINK_REQUIRE_COMPILED is set")
        pytest.skip(f"{NAME} is not built here ({_accel.describe()})")
    spec = importlib.util.spec_from_file_location(NAME, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def c() -> Any:
    return _load()


def _pure_seal(body: bytes) -> bytes:
    return body + struct.pack("<H", crc16_x25_reference(body))


def _pure_patch(template: bytes, cycle_at: int, cycle: int, wdt_at: int, wdt: int) -> bytes:
    buf = bytearray(template)
    struct.pack_into("<I", buf, cycle_at, cycle)
    buf[wdt_at] = wdt
    return _pure_seal(bytes(buf))


def test_check_value(c):
    assert c.crc16_x25(b"123456789") == 0x906E  # CRC-16/X-25's catalogued check value
    assert c.crc16_x25(b"") == 0


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_crc_seal_and_check_equal_the_pure_ones(c, data):
    want = crc16_x25_reference(data)
    for form in (data, bytearray(data), memoryview(data)):
        assert c.crc16_x25(form) == want == crc16_x25_pure(form)
        sealed = c.seal(form)
        assert type(sealed) is bytes and sealed == _pure_seal(data)
    assert c.fcs_ok(_pure_seal(data)) is True
    assert c.fcs_ok(data) is (len(data) >= 2 and crc16_x25_reference(data[:-2]) == int.from_bytes(data[-2:],
                                                                                                  "little"))


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=2, max_size=80), st.integers(0, 79), st.integers(0, 7))
def test_fcs_ok_rejects_every_single_bit_flip(c, data, at, bit):
    sealed = bytearray(_pure_seal(data))
    sealed[at % len(sealed)] ^= 1 << bit
    assert c.fcs_ok(bytes(sealed)) is False  # a CRC-16 detects every single-bit error


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_patch_seal_equals_the_pure_patch(c, data):
    template = data.draw(st.binary(min_size=5, max_size=80))
    cycle_at = data.draw(st.integers(0, len(template) - 4))
    wdt_at = data.draw(st.integers(0, len(template) - 1))
    cycle, wdt = data.draw(st.integers(0, 0xFFFF_FFFF)), data.draw(st.integers(0, 0xFF))
    for form in (template, bytearray(template)):
        before = bytes(form)
        out = c.patch_seal(form, cycle_at, cycle, wdt_at, wdt)
        assert type(out) is bytes and out == _pure_patch(template, cycle_at, cycle, wdt_at, wdt)
        assert bytes(form) == before  # the template is not changed


@pytest.mark.parametrize("args, error", [
    ((b"\0" * 16, 13, 0, 0, 0), ValueError),          # the cycle field runs past the end
    ((b"\0" * 16, 0, 0, 16, 0), ValueError),          # the WDT byte past the end
    ((b"\0" * 16, 0, 1 << 32, 0, 0), ValueError),     # the cycle is a u32
    ((b"\0" * 16, 0, -1, 0, 0), ValueError),
    ((b"\0" * 16, 0, 0, 0, 256), ValueError),          # the WDT is a byte
    ((b"\0" * 16, 0, 0, 0, "1"), TypeError),
    ((b"\0" * 16, 0, 0, 0), TypeError),                # four arguments
    (("not bytes", 0, 0, 0, 0), TypeError),
])
def test_patch_seal_refuses_bad_arguments(c, args, error):
    with pytest.raises(error):
        c.patch_seal(*args)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_steady_delta_inverts_patch_seal_and_equals_the_cores_own(c, data):
    """steady_delta (C) and mlink_sim.wire.frame.steady_delta (C when compiled, the pure fallback with
    MLINK_PURE=1): cycle | wdt << 32 for a datagram that differs from the previous one only in its cycle, WDT and
    FCS; -1 for any other change, a bad FCS or another length."""
    template = data.draw(st.binary(min_size=6, max_size=80))
    cycle_at = data.draw(st.integers(0, len(template) - 4))
    wdt_at = data.draw(st.integers(0, len(template) - 1).filter(lambda i: not cycle_at <= i < cycle_at + 4))
    cycle, wdt = data.draw(st.integers(0, 0xFFFF_FFFF)), data.draw(st.integers(0, 0xFF))
    previous = c.patch_seal(template, cycle_at, data.draw(st.integers(0, 0xFFFF_FFFF)), wdt_at,
                            data.draw(st.integers(0, 0xFF)))
    now = c.patch_seal(template, cycle_at, cycle, wdt_at, wdt)
    for fn in (c.steady_delta, frame.steady_delta):
        assert fn(now, previous, cycle_at, wdt_at) == cycle | wdt << 32
    assert c.steady_delta(bytearray(now), memoryview(previous), cycle_at, wdt_at) == cycle | wdt << 32
    at, bit = data.draw(st.integers(0, len(now) - 1)), data.draw(st.integers(0, 7))
    changed = bytearray(now)
    changed[at] ^= 1 << bit
    resealed = c.seal(bytes(changed[:-2]))
    for fn in (c.steady_delta, frame.steady_delta):
        assert fn(bytes(changed), previous, cycle_at, wdt_at) == -1  # a bad FCS, wherever the flip is
        if at < len(now) - 2 and not cycle_at <= at < cycle_at + 4 and at != wdt_at:
            assert fn(resealed, previous, cycle_at, wdt_at) == -1  # another field changed, sealed right
        assert fn(now + b"\0", previous, cycle_at, wdt_at) == -1
        assert fn(now[:-1], previous, cycle_at, wdt_at) == -1


def _pure_delta(now: bytes, previous: bytes, cycle_at: int, wdt_at: int) -> int:
    """steady_delta spelt out byte by byte (the C module compares the stretches between the holes at once)."""
    body = len(now) - 2
    if len(now) != len(previous) or len(now) < 2:
        return -1
    if any(now[i] != previous[i] for i in range(body) if not cycle_at <= i < cycle_at + 4 and i != wdt_at):
        return -1
    if _pure_seal(now[:body]) != now:
        return -1
    return struct.unpack_from("<I", now, cycle_at)[0] | now[wdt_at] << 32


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_steady_delta_compares_every_byte_outside_the_two_holes(c, data):
    """Any two datagrams of one length, any offsets (the WDT byte before, after or inside the cycle field): the C
    module's answer is the byte-by-byte one, whichever byte differs."""
    body = data.draw(st.binary(min_size=5, max_size=70))
    cycle_at = data.draw(st.integers(0, len(body) - 4))
    wdt_at = data.draw(st.integers(0, len(body) - 1))
    now = _pure_seal(body)
    changed = bytearray(body)
    for at in data.draw(st.lists(st.integers(0, len(body) - 1), max_size=3)):
        changed[at] ^= data.draw(st.integers(1, 255))
    previous = _pure_seal(bytes(changed))
    assert c.steady_delta(now, previous, cycle_at, wdt_at) == _pure_delta(now, previous, cycle_at, wdt_at)
    assert frame.steady_delta(now, previous, cycle_at, wdt_at) == _pure_delta(now, previous, cycle_at, wdt_at)


@pytest.mark.parametrize("args, error", [
    ((b"\0" * 16, b"\0" * 16, 11, 0), ValueError),   # the cycle field runs into the FCS
    ((b"\0" * 16, b"\0" * 16, 0, 14), ValueError),   # the WDT byte is the FCS
    ((b"\0" * 16, b"\0" * 16, -1, 0), ValueError),
    ((b"\0" * 16, b"\0" * 16, 0), TypeError),       # three arguments
    (("not bytes", b"\0" * 16, 0, 4), TypeError),
    ((b"\0" * 16, None, 0, 4), TypeError),
])
def test_steady_delta_refuses_bad_arguments(c, args, error):
    with pytest.raises(error):
        c.steady_delta(*args)


def test_non_bytes_are_a_type_error(c):
    for fn in (c.crc16_x25, c.seal, c.fcs_ok):
        with pytest.raises(TypeError):
            fn("text")


def test_the_cores_use_it_exactly_when_compiled():
    """Compiled cores: mlink_sim.wire.fcs.NATIVE is the C module; pure cores (MLINK_PURE=1): None, and its
    import is refused, so one process never mixes the two."""
    code = ("import mlink_sim, mlink_sim._accel as a, mlink_sim.wire.fcs as f\n"
            "try:\n    import mlink_sim.wire._fcsc\n    imported = 'yes'\n"
            "except ModuleNotFoundError as exc:\n    imported = str(exc)\n"
            "print(a.MODE, f.NATIVE is not None, imported)")
    env = {**os.environ, "MLINK_PURE": "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.split(" ", 2)
    assert out[:2] == ["pure", "False"]
    assert out[2].startswith(f"{NAME}: the cores run pure Python (MLINK_PURE is set)")
    env["MLINK_PURE"] = "0"
    mode, native, imported = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                            check=True, cwd=ROOT).stdout.strip().split(" ", 2)
    assert native == ("True" if mode == "compiled" else "False")
    if mode == "compiled":
        assert imported == "yes"
