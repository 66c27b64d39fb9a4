"""``wire.frame.datagram_offset``: byte offsets of data-frame fields in a whole datagram, from the declarations."""

import pytest

from mlink_sim.wire import ml2, ml3
from mlink_sim.wire.frame import HEADER_SIZE, datagram_offset


def test_wdt_is_byte_16_of_the_ml2_command_after_the_envelope():
    # SI-T3 command tables (e.g. Table 9, NOP): "16 WDT RWDT", byte 16 counted from 1 in the data frame.
    assert datagram_offset("wdt", ml2.COMMAND_FRAME_17, ml2.COMMAND_FRAME_32) == HEADER_SIZE + 15


@pytest.mark.parametrize("frame", [ml2.COMMAND_FRAME_32, ml3.COMMAND_FRAME_32, ml3.COMMAND_FRAME_64])
@pytest.mark.parametrize("name", ["wdt", "subcode"])
def test_offset_equals_where_the_built_frame_puts_the_field(frame, name):
    if name not in {k for k in frame.parse(bytes(frame.sizeof()))}:
        pytest.skip(f"{name} is not in this frame")
    assert datagram_offset(name, frame) == HEADER_SIZE + _offset_by_building(frame, name)


def _offset_by_building(frame, name):
    """Where a marker written into field *name* lands when the frame is built (the declaration read the other way)."""
    values = {k: (0 if not isinstance(v, bytes) else bytes(len(v))) for k, v in frame.parse(bytes(frame.sizeof())).items()
              if not k.startswith("_")}
    values[name] = 0xA5
    return frame.build(values).index(0xA5)


def test_fields_at_different_places_are_refused():
    # the WDT is byte 16 of an ML-II frame but not of an ML-III one: no single offset exists
    with pytest.raises(ValueError, match="not at one place"):
        datagram_offset("wdt", ml2.COMMAND_FRAME_32, ml3.COMMAND_FRAME_64)
