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
from typing import ClassVar

from mlink_sim.wire import Link, M2Cmd

from .ml2_card import MAIN_HANDLERS, SUB_HANDLERS, Ml2Station
from .settings import CardSettings

__all__ = ["SiT3"]


class SiT3(Ml2Station):
    """SI-T3 MECHATROLINK-II option card on an A1000-family drive."""

    card: ClassVar[str] = "si-t3"
    family: ClassVar[str] = "a1000"
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
