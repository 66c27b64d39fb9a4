"""FCS of the UDP wire contract: CRC-16/X-25 (docs/wire-format.md "Frame check sequence")."""

from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim.wire import crc16_x25
from mlink_sim.wire.fcs import crc16_x25_reference

CHECK_INPUT = b"123456789"
CHECK_VALUE = 0x906E  # the catalogued check value of CRC-16/X-25 (a.k.a. CRC-16/IBM-SDLC)


def test_check_value_fast():
    assert crc16_x25(CHECK_INPUT) == CHECK_VALUE


def test_check_value_reference():
    assert crc16_x25_reference(CHECK_INPUT) == CHECK_VALUE


def test_empty_input_is_init_xor_xorout():
    # init 0xFFFF, no data, xorout 0xFFFF -> 0x0000
    assert crc16_x25(b"") == crc16_x25_reference(b"") == 0x0000


def test_residue_over_data_and_fcs():
    # Appending the FCS little-endian gives the constant X-25 residue 0xF0B8 (before xorout: "good FCS" 0x0F47).
    data = b"\x4d\x02\x01\x21" + bytes(range(40))
    fcs = crc16_x25(data)
    assert crc16_x25_reference(data + fcs.to_bytes(2, "little")) ^ 0xFFFF == 0xF0B8


def test_accepts_bytearray_and_memoryview():
    assert crc16_x25(bytearray(CHECK_INPUT)) == crc16_x25(memoryview(CHECK_INPUT)) == CHECK_VALUE


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_fast_equals_reference(data):
    assert crc16_x25(data) == crc16_x25_reference(data)
