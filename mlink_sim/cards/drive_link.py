"""The one place the cards touch the drive model (``mlink_sim.drive``).

Everything a card needs from the drive goes through :class:`DriveLink`: building settings from the card's
parameter store, the network command, card-detected causes (bUS per F6-01, E5 per F6-25, the CyC/AEr minor
faults), fault reset, monitors and the fault history, which the card persists in its EEPROM image
(the drive keeps only what happened since power-up; the history restored from EEPROM is appended here).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from mlink_sim.drive import (
    Drive,
    DriveCommand,
    DriveSettings,
    DriveStatus,
    Family,
    Fault,
    LoadSpec,
    StopMethod,
    fault_code,
    hz_to_ref,
    minor_code,
    ml2_status_bits,
    ml3_invcmd_stat_bits,
)

from mlink_sim.drive.monitors import monitor_reader, read_monitor
from mlink_sim.wire.selections import SEL_MON_TABLES

from .eeprom import HISTORY_DEPTH
from .snapshot import DriveSnapshot

__all__ = [
    "DriveLink",
    "DriveCommand",
    "DriveStatus",
    "Fault",
    "LoadSpec",
    "StopMethod",
    "ml2_status_bits",
    "ml3_invcmd_stat_bits",
    "fault_by_name",
]

_FAULTS_BY_DISPLAY = {f.value: f for f in Fault}


def fault_by_name(name: str) -> Fault | None:
    """A :class:`Fault` by its stored name (the enum value, e.g. ``"bUS"``), or None."""
    return _FAULTS_BY_DISPLAY.get(name)


class DriveLink:
    """A drive of *family* ("a1000" / "v7") driven by one card, whose SEL_MON table is *selections* (its key in
    :data:`~mlink_sim.wire.selections.SEL_MON_TABLES`, the card profile's ``selections``)."""

    __slots__ = ("family", "drive", "_restored", "_sel_mon", "_mon_static", "mon_readers")

    def __init__(self, family: str, selections: str, values: Mapping[str, int], load: LoadSpec | None,
                 now: int, history: Iterable[str] = ()) -> None:
        self.family = Family(family)
        settings = DriveSettings.from_params(self.family, values)
        if load is None:
            load = LoadSpec.for_motor(settings)
        self.drive = Drive(self.family, settings, load, now=now)
        restored = [fault_by_name(n) for n in history]
        self._restored: list[Fault] = [f for f in restored if f is not None][:HISTORY_DEPTH]
        self._sel_mon = SEL_MON_TABLES.get(selections, ("",) * 16)  # the card's (CardProfile.selections)
        # SEL_MON codes whose value only the drive's state decides (SI-T3 Table 18 / SI-ET3 Table 22 / SI-T/V7 Table 5):
        # not the fault history (U2-xx, U3-xx, U-09) nor a parameter (F6-23/F6-24).
        self._mon_static = tuple(
            name in ("", "ALARM", "WARNING") or name.startswith(("U1-", "U-")) and name != "U-09"
            for name in self._sel_mon)
        #: by SEL_MON code, the drive model's own reader of a plain monitor (U1-xx, U-xx but U-09: what
        #: :meth:`monitor` reads through :func:`read_monitor`), resolved once; None for what the card resolves
        #: (nothing selected, ALARM, WARNING, F6-23/F6-24, the fault history)
        self.mon_readers = tuple(
            monitor_reader(self.family, name) if name.startswith(("U1-", "U-")) and name != "U-09" else None
            for name in self._sel_mon)

    # -- time and commands ------------------------------------------------------------------------
    def advance(self, now: int) -> None:
        self.drive.advance(now)

    def command(self, cmd: DriveCommand, now: int) -> None:
        if cmd.fault_history_clear and not self.drive.command_in_effect.fault_history_clear:
            self._restored.clear()
        self.drive.command(cmd, now)

    def settings_for(self, values: Mapping[str, int]) -> DriveSettings:
        """The drive settings *values* (raw, by name) give; ``KeyError`` / ``ValueError`` for values the drive cannot
        take."""
        return DriveSettings.from_params(self.family, values)

    def apply(self, settings: DriveSettings, now: int) -> None:
        """The drive takes *settings* (CONFIG; oPE while they are inconsistent)."""
        self.drive.reconfigure(settings, now)

    def trip(self, fault: Fault, stop: int, now: int) -> None:
        self.drive.trip(fault, StopMethod(stop), now)

    def trip_bus(self, now: int) -> bool:
        """bUS after F6-26 communication alarms, per F6-01; only when run or reference come from the option
        (SI-T3 / SI-ET3 "bUS ... Only detected when the run command or frequency reference is assigned to the
        option"; SI-T3 Table 28 bUS "After establishing initial communication, the connection was lost"). False when
        not detected."""
        s = self.drive.settings
        if not (s.run_from_network or s.ref_from_network):
            return False
        self.drive.trip(Fault.BUS, s.bus_stop, now)
        return True

    def trip_e5(self, now: int) -> None:
        """E5 watchdog error, per F6-25 (V7: a fault, Table 10 E5H)."""
        self.drive.trip(Fault.E5, self.drive.settings.e5_stop, now)

    def minor(self, fault: Fault, on: bool, now: int) -> None:
        """Raise or clear a card minor fault (CyC, AEr – SI-T3 Table 27)."""
        if on:
            self.drive.trip(fault, StopMethod.ALARM_ONLY, now)
        else:
            self.drive.clear_minor(fault, now)

    def reset_fault(self, now: int) -> bool:
        return self.drive.reset_fault(now)

    def clear_fault_history(self) -> None:
        self._restored.clear()
        self.drive.clear_fault_history()

    # -- status ------------------------------------------------------------------------------------
    @property
    def status(self) -> DriveStatus:
        return self.drive.status

    @property
    def settings(self) -> DriveSettings:
        return self.drive.settings

    def fault_code(self, fault: Fault | None) -> int:
        return fault_code(self.family, fault)

    def minor_code(self, fault: Fault | None) -> int:
        return minor_code(self.family, fault)

    def history(self) -> tuple[Fault, ...]:
        """Fault history, most recent first (max 10): since power-up, then restored from EEPROM."""
        return (self.drive.fault_history + tuple(self._restored))[:HISTORY_DEPTH]

    def history_names(self) -> tuple[str, ...]:
        return tuple(f.value for f in self.history())

    def snapshot(self) -> DriveSnapshot:
        """The drive as a status display shows it (``Station.snapshot().drive``)."""
        status = self.drive.status
        model = self.drive
        return DriveSnapshot(
            running=status.running, reverse=status.reverse, output_hz=abs(model.output_frequency_hz),
            reference_hz=model.frequency_reference_hz, output_current_a=model.output_current_a,
            dc_bus_v=model.dc_bus_v, motor_rpm=model.motor_speed_rpm, ready=status.ready, remote=status.remote,
            baseblock=status.baseblock, fault=status.fault.display if status.fault is not None else None,
            minors=tuple(sorted(f.display for f in status.minors)), ope=status.ope_code,
            fault_history=tuple(f.display for f in self.history()),
        )

    def output_freq_raw(self) -> int:
        """Output frequency in o1-03 / n035 units, unsigned (INV_CTL response)."""
        return abs(hz_to_ref(self.drive.settings, self.drive.output_frequency_hz)) & 0xFFFF

    def output_current_raw(self) -> int:
        """Output current in 0.1 A (SI-ET3 ID_CODE 4AH; SI-T3 / SI-T/V7 INV_CTL response)."""
        return int(self.drive.output_current_a * 10.0 + 0.5) & 0xFFFF

    def monitor(self, name: str) -> int:
        """U1/U2/U3 or U-xx monitor, raw; U2-01/U2-02/U3-xx, U-09 and n178 come from :meth:`history`."""
        if name == "n178":  # SI-T/V7 ALM_RD "n178 (Fault History)": read as the most recent fault code
            name = "U-09"
        if name.startswith(("U2-0", "U3-", "U-09")):
            hist = self.history()
            cur = self.drive.status.fault
            if name == "U2-01":
                return self.fault_code(cur)
            if name == "U2-02":
                prev = hist[1:2] if cur is not None else hist[0:1]
                return self.fault_code(prev[0]) if prev else 0
            if name == "U-09":
                return self.fault_code(hist[0]) if hist else 0
            if name.startswith("U3-"):
                try:
                    idx = int(name[3:])
                except ValueError:
                    return 0
                if 1 <= idx <= HISTORY_DEPTH:
                    return self.fault_code(hist[idx - 1]) if idx <= len(hist) else 0
        try:
            return int(read_monitor(self.drive, name))  # = Drive.monitor(), without its per-call import
        except Exception:  # noqa: BLE001 - a monitor the model does not know reads 0
            return 0

    def sel_mon_name(self, code: int) -> str:
        """What SEL_MON *code* selects on this card: a monitor name, "ALARM", "WARNING", "F6-23", "F6-24" or
        "" (nothing / not used) – SI-T3 Table 18, SI-ET3 Table 22, SI-T/V7 Table 5."""
        return self._sel_mon[code & 0xF]

    def is_steady(self) -> bool:
        return self.drive.is_steady

    def quiet_until(self) -> int:
        """:meth:`Drive.quiet_until <mlink_sim.drive.drive.Drive.quiet_until>`: the first instant the drive may show
        anything new (-1: now)."""
        return self.drive.quiet_until()

    def outputs_key(self, sel_mon: int) -> int:
        """A key under which the INV_CTL response's output frequency, current, MON1 and MON2 stay the same: set
        while the drive is steady and both SEL_MON codes show drive state (-1: compute them). An int, the steady
        epoch and the SEL_MON byte (``Int8ul`` in the wire declarations), so that the per-cycle check allocates
        nothing."""
        d = self.drive
        static = self._mon_static
        if sel_mon <= 0xFF and d.is_steady and static[sel_mon & 0xF] and static[sel_mon >> 4 & 0xF]:
            return d.steady_epoch << 8 | sel_mon
        return -1

