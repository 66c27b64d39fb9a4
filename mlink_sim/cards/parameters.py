"""PRM_RD, PRM_WR and CONFIG: a station's parameter operations, the same on every card (the handlers of
:mod:`mlink_sim.cards.commands` call them).

The values live in the station's :class:`~mlink_sim.cards.paramstore.ParamStore` (written values wait there
until CONFIG applies them, except on the SI-T/V7, whose PRM_WR takes effect at once: ``Station.prm_immediate``);
applied values reconfigure the drive model; CONFIG_MOD = 1 also marks the EEPROM image dirty
(:class:`~mlink_sim.cards.eeprom.EepromWriteBack`). :func:`keypad_read` / :func:`keypad_write`: a parameter by name as the
drive's keypad reads and sets it (a standalone slave's ``get-param`` / ``set-param``, docs/control.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mlink_sim.params import Param, ParamError

from .results import Err

if TYPE_CHECKING:
    from .base import Station

__all__ = ["read_params", "write_params", "config", "reconfigure", "keypad_read", "keypad_write"]


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
            reconfigure(station, now)
        station._log.debug("prm_wr", values=changes, pending=not station.prm_immediate)
    return err


def config(station: Station, mod: int, now: int, *, sub: bool = False) -> Err:
    """CONFIG (SI-T3 Table 12, SI-ET3 Table 15, SI-T/V7 CONFIG): 0 = RAM, 1 = RAM and EEPROM. With
    ``eeprom.enabled`` the EEPROM store is complete only once the image is durable (``EepromWriteBack.hold``)."""
    if mod not in (0, 1):
        return Err.DATA
    if not station.prm_immediate and station.store.apply():
        reconfigure(station, now)
    if mod == 1:
        station.saved_params = station.store.overrides()
        station.eeprom.changed(config_sub=sub)
        station._log.info("eeprom_dirty", reason="CONFIG_MOD=1", params=len(station.saved_params))
    return Err.OK


def reconfigure(station: Station, now: int) -> None:
    """The drive model takes the applied values; a combination it cannot take keeps the old settings (logged)."""
    try:
        station.drive.reconfigure(station.store.active, now)
    except (KeyError, ValueError) as exc:
        station._log.warning("drive_reconfigure_failed", reason=str(exc))


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
    station.store.pending.pop(param.name, None)
    station.store.active[param.name] = raw
    reconfigure(station, now)
    station._log.info("keypad_write", param=param.name, raw=raw, save=save)
    if save:
        station.saved_params = station.store.overrides()
        station.eeprom.changed(config_sub=False)
    return Err.OK
