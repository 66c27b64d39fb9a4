"""SI-T3: the A1000 MECHATROLINK-II option card (YASKAWA SIEP C730600 50, with its errata).

* Power-up settings (Table 4, note <3>): F6-20 station address 20H–3FH (20H/3FH: AEr, the ERR light turns on
  and the card does not answer – note <4>); F6-21 frame size (0 = 32-byte, 1 = 17-byte); F6-22 link speed
  (0 = 10 Mbps MECHATROLINK-II, 1 = 4 Mbps MECHATROLINK-I, 17-byte only – Table 29 <3>); F6-23/F6-24 the
  registers of SEL_MON E/F.
* Commands: Tables 5/6; phases and combinations in :mod:`mlink_sim.cards.phases` (Table 7); handlers in
  :mod:`mlink_sim.cards.ml2_card`. PRM_WR values wait for CONFIG (Table 12). ALM_RD modes 0/1/2 (Tables 13/14).
  SEL REF Table 17, SEL MON Table 18.
* Alarms: Tables 19–25; drive codes Tables 26/27. bUS after F6-26 communication alarms, per F6-01; E5 per F6-25.
* LEDs (Table 3): RUN, ERR, TX, RX.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from mlink_sim.wire import Link, M2Cmd

from .ml2_card import MAIN_HANDLERS, SUB_HANDLERS, Ml2Station
from .settings import CardSettings

__all__ = ["SiT3", "MANUAL_TABLES"]


class SiT3(Ml2Station):
    """SI-T3 MECHATROLINK-II option card on an A1000-family drive."""

    handlers = MAIN_HANDLERS
    sub_handlers = MappingProxyType({code: handler for code, handler in SUB_HANDLERS.items()
                                     if code != M2Cmd.CONFIG})  # Table 6: no CONFIG sub-command

    def _power_up(self, values: Mapping[str, int], settings: CardSettings) -> None:
        self.address = values["F6-20"]
        self.link = Link.ML1 if values["F6-22"] == 1 else Link.ML2
        size = 17 if values["F6-21"] == 1 else 32
        if self.link is Link.ML1 and size == 32:
            self._log0.warning("frame_size_forced", reason="MECHATROLINK-I carries 17-byte frames only", size=17)
            size = 17
        self.data_size = size
        if not 0x21 <= self.address <= 0x3E:
            self.station_error = "AEr"  # Table 4 <4>, Table 27 32H
        self._mon_regs = {"F6-23": values["F6-23"], "F6-24": values["F6-24"]}

    def _bus_limit(self) -> int:
        return self.store.active.get("F6-26", 2)

    def _leds(self) -> tuple[dict[str, str], dict[str, str]]:
        """Table 3: RUN on once powered up; ERR on for a connection or communications error (AEr, E5/E6 –
        Table 20 "LED (ERR) ON" for communications alarms); TX/RX while data is sent/received."""
        err = self.station_error is not None or self.alarms.comm_alarm is not None
        leds = {
            "RUN": "on",
            "ERR": "on" if err else "off",
            "TX": "on" if self._led_recent(self._tx_at) else "off",
            "RX": "on" if self._led_recent(self._any_rx) else "off",
        }
        return leds, {"RUN": "green", "ERR": "red", "TX": "green", "RX": "green"}

#: Every table of the SI-T3 manual -> where it is implemented (``mlink_sim.``-relative), or None for hardware the
#: simulator does not model. Each target cites the table by its own number ("SI-T3 Table n");
#: tests/cards/test_manual_tables.py checks titles against the manual, targets and citations.
MANUAL_TABLES: Mapping[int, tuple[str, str | None]] = MappingProxyType({
    1: ("Contents of Package", None),
    2: ("Communication connector", None),
    3: ("MECHATROLINK-II Operation LED Status", "cards.si_t3.SiT3._leds"),
    4: ("Parameter Settings", "cards.si_t3.SiT3._power_up"),
    5: ("Main Commands", "cards.ml2_card.MAIN_HANDLERS"),
    6: ("Sub-commands", "cards.si_t3.SiT3.sub_handlers"),
    7: ("Main Command and Sub-command", "wire.combinations.ML2_COMBINATIONS"),
    8: ("Example when reading C1-01 (200H)", "cards.paramstore.ParamStore.read"),
    9: ("Example when writing in C1-01 (200H)", "cards.paramstore.ParamStore.write"),
    10: ("DEVICE_CODE", "cards.idinfo.ML2_ID_AREAS"),
    11: ("Vender Code (DEVICE_CODE = 0FH)", "cards.idinfo.ML2_ID_AREAS"),
    12: ("CONFIG_MOD", "cards.parameters.config"),
    13: ("ALM_RD_MOD", "cards.ml2_card.Ml2Station._alm_data"),
    14: ("ALM_DATA", "cards.ml2_card.Ml2Station._alm_data"),
    15: ("ALM_CLR_MOD", "cards.commands.alm_clr"),
    16: ("Operation Signals", "cards.ml2_card.Ml2Station._inv_ctl"),
    17: ("SEL REF1/2 (3/4, 5/6) Selection Range", "wire.selections.SEL_REF_TABLES"),
    18: ("SEL MON1/2 (3/4, 5/6) Selection Range", "wire.selections.SEL_MON_TABLES"),
    19: ("Fault Type", "cards.alarms.Ml2Alarms"),
    20: ("Fault Type and SI-T3 Processing", "cards.alarms.Ml2Alarms"),
    21: ("Response Data for Consecutive Alarms and/or Warnings", "cards.alarms.Ml2Alarms.report"),
    22: ("Reception Failures in Each Phase", "cards.alarms.ML2_RECEPTION_FAILURES"),
    23: ("Alarm Code (MECHATROLINK-II Response ALARM Value)", "wire.codes.M2Alarm"),
    24: ("Fault Types", "cards.reception.FailureKind"),
    25: ("Other fault detected by SI-T3", "cards.results.Err"),
    26: ("Drive Alarm Codes", "drive.faults.SI_T3_FAULT_CODES"),
    27: ("Drive Minor Fault and Alarm", "drive.faults.SI_T3_MINOR_CODES"),
    28: ("Fault Display and Possible Solutions", "cards.drive_link.DriveLink.trip_bus"),
    29: ("Option Specifications", "cards.si_t3.SiT3._power_up"),
})
