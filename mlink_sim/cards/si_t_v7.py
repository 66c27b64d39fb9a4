"""SI-T/V7: the VS-606V7 MECHATROLINK-I/II communications interface unit (SI-T/V7 technical manual).

* Power-up settings (§3.4): DIP switch S1-1 baud rate (OFF 4 Mbps MECHATROLINK-I, ON 10 Mbps), S1-2 data length
  (OFF 17-byte, ON 32-byte; "Invalid if S1-1 is OFF (4 Mbps) and S1-2 is ON" – 17-byte then), station number
  from S1-3 (tens digit 2/3) and rotary switch S2 (ones digit); 20H and 3FH "will be faulty": the ERR indicator
  blinks six times, RUN is off and the unit does not answer.
* Commands: Tables 1/2 plus the CONFIG sub-command (§7.2). In 32-byte mode PRM_RD/PRM_WR are accepted only as
  sub-commands ("If received as a main command in 32-byte mode: Command alarm (A.95)";
  ``CardOptions.v7_prm_main_in_32byte`` accepts them). PRM_WR takes effect at once (CONFIG_MOD 0 "Not
  required"); CONFIG_MOD 1 saves to EEPROM. ALM_RD modes 0 and 1 (n178, two faults). SEL REF Table 4,
  SEL MON Table 5 (n035 units).
* Alarms: §8, Tables 6–11. A communications alarm is notified to the inverter at once (§8.1 "Notification
  to Inverter"): it faults BUS (Table 10 E6H) when run or reference come from the option (n003 = 3 / n004 = 9).
* LEDs (§3.3): RUN, ERR, TX, RX.
* Table 12 (causes of the faults the Digital Operator displays): the display names of
  :class:`mlink_sim.drive.faults.Fault`, coded per Table 10 / Table 11.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from types import MappingProxyType
from typing import Any, ClassVar

from mlink_sim.wire import Frame, Link, M2Cmd

from .commands import Handler
from .idinfo import V7_ID_AREAS
from .ml2_card import MAIN_HANDLERS, SUB_HANDLERS, Ml2Station, echo_main
from .phases import V7_COMBINATIONS, V7_SUB_PHASES
from .results import Err
from .settings import CardSettings

__all__ = ["SiTV7", "MANUAL_TABLES"]


def _sub_command_only_in_32byte(handler: Handler) -> Handler:
    """PRM_RD / PRM_WR: "If the MECHATROLINK-II 32-byte mode is used, PRM_RD can be used only in a sub-command" –
    "If received as a main command in 32-byte mode: Command alarm (A.95)" (``CardOptions.v7_prm_main_in_32byte``
    accepts them, docs/cards.md)."""

    def main_command(station: Any, body: Any, frame: Frame, source: Hashable, now: int) -> tuple[Any, Err]:
        if station.data_size == 32 and not station.options.v7_prm_main_in_32byte:
            return echo_main(body), Err.CONDITION
        return handler(station, body, frame, source, now)

    return main_command


class SiTV7(Ml2Station):
    """SI-T/V7 MECHATROLINK-I/II interface unit on a VS-606V7 inverter."""

    prm_immediate: ClassVar[bool] = True
    has_cyc: ClassVar[bool] = False
    alm_rd_history: ClassVar[int] = 2  # ALM_RD mode 1: two history entries (SI-T/V7 ALM_RD)
    mfi_mask: ClassVar[int] = 0x1F  # Table 3: bits 2–6 = S3–S7, bit 7 not used
    sub_phases = V7_SUB_PHASES
    combinations = V7_COMBINATIONS
    id_areas = V7_ID_AREAS
    alm_rd_modes = frozenset((0, 1))
    handlers = MappingProxyType({
        **MAIN_HANDLERS,
        M2Cmd.PRM_RD: _sub_command_only_in_32byte(MAIN_HANDLERS[M2Cmd.PRM_RD]),
        M2Cmd.PRM_WR: _sub_command_only_in_32byte(MAIN_HANDLERS[M2Cmd.PRM_WR]),
    })
    sub_handlers = SUB_HANDLERS  # with the CONFIG sub-command (§7.2)

    def _power_up(self, values: Mapping[str, int], settings: CardSettings) -> None:
        station = settings.station if settings.station is not None else 0x21
        if not 0x20 <= station <= 0x3F:
            raise ValueError(f"SI-T/V7: station {station:02X}H cannot be set with S1-3 and S2 (20H–3FH)")
        self.address = station
        self.link = Link.ML2 if settings.s1_1_10mbps else Link.ML1
        self.data_size = 32 if settings.s1_2_32byte and settings.s1_1_10mbps else 17
        if settings.s1_2_32byte and not settings.s1_1_10mbps:
            self._log0.warning("frame_size_forced", reason="S1-2 is invalid with S1-1 OFF (4 Mbps)", size=17)
        if station in (0x20, 0x3F):
            self.station_error = "AEr"  # §3.4 "Fault"; ERR blinks six times

    def _leds(self) -> tuple[dict[str, str], dict[str, str]]:
        """§3.3: RUN lit in normal operation, off on a station address setting error; ERR lit for a watchdog
        timeout or communications error, blinking for a station address setting error; TX sending; RX
        receiving carrier."""
        bad_address = self.station_error is not None
        err = "blink" if bad_address else ("on" if self.alarms.comm_alarm is not None else "off")
        leds = {
            "RUN": "off" if bad_address else "on",
            "ERR": err,
            "TX": "on" if self._led_recent(self._tx_at) else "off",
            "RX": "on" if self._led_recent(self._any_rx) else "off",
        }
        return leds, {"RUN": "green", "ERR": "red", "TX": "green", "RX": "green"}

#: Every numbered table of the SI-T/V7 manual -> where it is implemented (``mlink_sim.``-relative). Each target
#: cites the table by its own number ("SI-T/V7 Table n" or "V7 Table n"); tests/cards/test_manual_tables.py checks
#: titles against the manual, targets and citations. (The ID_RD and phase tables of the manual are unnumbered.)
MANUAL_TABLES: Mapping[int, tuple[str, str | None]] = MappingProxyType({
    1: ("Main Commands", "cards.ml2_card.MAIN_HANDLERS"),
    2: ("Sub-commands", "cards.ml2_card.SUB_HANDLERS"),
    3: ("Operation Signals", "cards.ml2_card.Ml2Station._inv_ctl"),
    4: ("SEL REF1/2 Selection Range", "wire.selections.SEL_REF_TABLES"),
    5: ("SEL MON1/2 Selection Range", "wire.selections.SEL_MON_TABLES"),
    6: ("Response Data for Consecutive Alarms and/or Warnings", "cards.alarms.Ml2Alarms.report"),
    7: ("Reception Failures in Each Phase", "cards.alarms.ML2_RECEPTION_FAILURES"),
    8: ("Alarm Code (MECHATROLINK-II Response ALARM Value)", "wire.codes.M2Alarm"),
    9: ("Fault Types", "cards.reception.FailureKind"),
    10: ("Inverter Alarm Codes", "drive.faults.V7_FAULT_CODES"),
    11: ("Inverter Warning Codes", "drive.faults.V7_WARNING_CODES"),
    12: ("Causes and Countermeasures of Main Faults Displayed on VSmini V7 Digital Operator", "cards.si_t_v7"),
})
