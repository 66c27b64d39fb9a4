"""PRM_RD, PRM_WR and CONFIG: a station's parameter operations, the same on every card (the handlers of
:mod:`mlink_sim.cards.commands` call them).

The values live in the station's :class:`~mlink_sim.cards.paramstore.ParamStore` (written values wait there
until CONFIG applies them, except on the SI-T/V7, whose PRM_WR takes effect at once: ``Station.prm_immediate``);
applied values reconfigure the drive model; CONFIG_MOD = 1 also marks the EEPROM image dirty
(:class:`~mlink_sim.cards.eeprom.EepromWriteBack`).

The answer first (``Station.finish``, docs/timing.md "When each command is answered"): the drive settings of the
values a PRM_WR leaves pending are built after its answer (:func:`prepare_settings`), so that CONFIG only applies them;
the values CONFIG_MOD = 1 stores are listed after its answer; a value in effect at once (SI-T/V7) reaches the drive
model after its PRM_WR's answer, before the card takes its next command. :func:`keypad_read` / :func:`keypad_write`: a parameter by name as the
drive's keypad reads and sets it (a standalone slave's ``get-param`` / ``set-param``, docs/control.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from mlink_sim.params import Param, ParamError

from .results import Err

if TYPE_CHECKING:
    from .base import Station

__all__ = ["read_params", "write_params", "config", "reconfigure", "prepare_settings", "keypad_read", "keypad_write"]


def read_params(station: Station, no: int, size: int) -> tuple[bytes, Err]:
    """PRM_RD (SI-T3 Table 8, SI-ET3 PRM_RD, SI-T/V7 PRM_RD): PARAMETER (8 bytes) and the verdict."""
    return station.store.read(no, size, station.drive.monitor)


def write_params(station: Station, no: int, size: int, data: bytes, now: int) -> Err:
    """PRM_WR (SI-T3 Table 9, SI-ET3 PRM_WR, SI-T/V7 PRM_WR)."""
    if not station.drive.status.main_power_on:
        return Err.UNDERVOLTAGE  # "During an undervoltage fault" / "Writing Error during Under Voltage"
    err, changes = station.store.write(no, size, data)
    if err is Err.OK:
        if station.prm_immediate:
            station._reconfigure_due = station.unfinished = True  # after the answer (Station.finish)
        else:
            station._prepare_due = station.unfinished = True  # the settings CONFIG will take, built after the answer
        station._note("debug", "prm_wr", {"values": changes, "pending": not station.prm_immediate})
    return err


def config(station: Station, mod: int, now: int, *, sub: bool = False) -> Err:
    """CONFIG (SI-T3 Table 12, SI-ET3 Table 15, SI-T/V7 CONFIG): 0 = RAM, 1 = RAM and EEPROM. With
    ``eeprom.enabled`` the EEPROM store is complete only once the image is durable (``EepromWriteBack.hold``)."""
    if mod not in (0, 1):
        return Err.DATA
    store = station.store
    if not station.prm_immediate:
        prepared = station._prepared
        ready = prepared[1] if prepared is not None and prepared[0] == store.version else None
        station._prepared = None
        if store.apply():
            reconfigure(station, now, ready)
    if mod == 1:
        station._save_due = "CONFIG_MOD=1"  # the values stored are listed after the answer (Station.finish)
        station.unfinished = True
        station.eeprom.changed(config_sub=sub)
    return Err.OK


def prepare_settings(station: Station) -> tuple[int, Any]:
    """The drive settings the pending values will give once CONFIG applies them (``DriveSettings``, or why the drive
    cannot take them), for the store as it is now (its version): what :func:`config` applies without building them."""
    store = station.store
    try:
        return store.version, station.drive.settings_for({**store.active, **store.pending})
    except (KeyError, ValueError) as exc:
        return store.version, str(exc)


def reconfigure(station: Station, now: int, ready: Any = None) -> None:
    """The drive model takes the applied values (*ready*: their settings as :func:`prepare_settings` built them, or
    why the drive cannot take them); a combination it cannot take keeps the old settings (logged)."""
    try:
        if ready is None:
            ready = station.drive.settings_for(station.store.active)
        if isinstance(ready, str):
            raise ValueError(ready)
        station.drive.apply(ready, now)
    except (KeyError, ValueError) as exc:
        station._note("warning", "drive_reconfigure_failed", {"reason": str(exc)})


def keypad_read(station: Station, name: str) -> tuple[Param, int]:
    """A parameter or monitor by name as the drive's keypad shows it (its row and raw value: the value in effect,
    or the one written and not yet entered; a monitor as the drive reads it now). ``ParamError`` for a name the
    station's table does not have."""
    param = station.store.table.resolve(name)
    raw = station.drive.monitor(param.name) if param.read_only else station.store.value(param.name)
    return param, raw


def keypad_write(station: Station, name: str, raw: int, now: int, *, save: bool) -> Err:
    """Set a parameter by name as the drive's keypad does: in effect at once (the drive model reconfigured), with
    *save* also stored as CONFIG_MOD = 1 stores it (the EEPROM image). ``Err.DATA`` for a monitor or a value outside
    the row's range, ``Err.UNDERVOLTAGE`` while the main power is off (as PRM_WR)."""
    param = station.store.table.resolve(name)
    if param.read_only:
        return Err.DATA
    try:
        station.store.table.check(param, raw)
    except ParamError:
        return Err.DATA
    if not station.drive.status.main_power_on:
        return Err.UNDERVOLTAGE
    station.finish()
    station.store.enter(param.name, raw)
    reconfigure(station, now)
    station._note("info", "keypad_write", {"param": param.name, "raw": raw, "save": save})
    if save:
        station._save_due = "keypad"
        station.unfinished = True
        station.eeprom.changed(config_sub=False)
    station.finish()
    return Err.OK
