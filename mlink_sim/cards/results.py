"""Command verdicts shared by the card classes, with their code on each generation.

MECHATROLINK-I/II report a refused command as a communications warning in the ALARM byte (SI-T3 Table 25,
SI-T/V7 "Other Faults"): A.94 data setting warning, A.95 command warning – "Received commands are ignored".
MECHATROLINK-III reports it in CMD_ALM / SUBCMD_ALM (SI-ET3 "CMD_ALM", SI-ET3 Table 25 "SUBCMD_ALM").
"""

from __future__ import annotations

import enum

__all__ = ["Err"]


class Err(enum.Enum):
    """Why a command was not executed; ``value`` = (MECHATROLINK-II ALARM code, MECHATROLINK-III CMD_ALM)."""

    OK = (0x00, 0x0)
    #: bad data: SIZE, register number, range, CONFIG_MOD, ALM_RD_MOD … (A.94 / CMD_ALM 9H)
    DATA = (0x94, 0x9)
    #: PRM_WR during undervoltage: SI-T3 "Command warning (A.95)", SI-ET3 PRM_WR table "9"
    UNDERVOLTAGE = (0x95, 0x9)
    #: a command code the card does not know (A.95 / CMD_ALM 8H)
    UNSUPPORTED = (0x95, 0x8)
    #: not executable in the present state (A.95 / CMD_ALM AH)
    CONDITION = (0x95, 0xA)
    #: main/sub-command combination (SI-T3 Table 7 A.95 / SI-ET3 Table 13 CMD_ALM BH)
    COMBINATION = (0x95, 0xB)
    #: not allowed in this phase (A.95 / CMD_ALM CH)
    PHASE = (0x95, 0xC)

    @property
    def ml2(self) -> int:
        return self.value[0]

    @property
    def ml3(self) -> int:
        return self.value[1]
