"""What the I/O layer asks of a station goes through its methods (docs/architecture.md, "The core interfaces"):
the drive's activity, EEPROM persistence and its generations, an internal error the layer found."""

from __future__ import annotations

import pytest

from mlink_sim.drive.activity import DriveActivity
from mlink_sim.wire import ml2, ml3

from .helpers import Master, station


@pytest.mark.parametrize("card", ["si-t3", "si-et3", "si-t-v7"])
def test_the_drive_activity_is_the_drives_own(card: str) -> None:
    st = station(card)
    activity = st.drive_activity()
    assert isinstance(activity, DriveActivity) and activity == st.drive.drive.activity()


def test_persisting_the_eeprom_and_the_generation_of_the_image_taken() -> None:
    m = Master(station("si-t3"))
    assert not m.st.eeprom.enabled  # a bare core persists nothing
    m.st.persist_eeprom(True)
    assert m.st.eeprom.enabled
    m.connect()
    m.send(ml2.Config(1))  # CONFIG_MOD 1: an image to store
    assert m.st.take_eeprom() is not None and m.st.eeprom_generation == m.st.eeprom.taken
    m.st.persist_eeprom(False)
    assert not m.st.eeprom.enabled


def test_an_internal_error_the_io_layer_records_is_counted_as_the_cards() -> None:
    st = station("si-et3")
    assert st.record_internal_error() == 1 and st.record_internal_error() == 2
    assert st.counters.internal_errors == 2 == st.snapshot().counters["internal_errors"]
    m = Master(st)
    m.connect()
    assert m.send(ml3.Nop()) is not None  # the station answers on
