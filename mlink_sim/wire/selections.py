"""What the INV_CTL / INV_I/O selection codes select: the manuals' SEL_REF and SEL_MON tables, as data.

INV_CTL carries SEL_REF1/2 and SEL_MON1/2 (INV_I/O 3/4 and 5/6 likewise), one 4-bit code per REF/MON word. The
one source of these tables; the drive (:mod:`mlink_sim.drive.monitors`, the value of a monitor) and the cards
(:mod:`mlink_sim.cards.monitors`, :mod:`mlink_sim.cards.drive_link`) read them, keyed as the manuals name the card
(``"SI-T3"``, ``"SI-ET3"``, ``"SI-T/V7"``); a card's profile says which it uses (``CardProfile.selections``,
:mod:`mlink_sim.profiles`).

================  =========================  =========================
card              SEL_REF                    SEL_MON
================  =========================  =========================
SI-T3             Table 17                   Table 18
SI-ET3            Table 21                   Table 22
SI-T/V7           Table 4                    Table 5
================  =========================  =========================

:data:`SEL_MON_TABLES`: code -> the monitor it reads (``"U1-05"``, V7 ``"U-02"``), ``""`` for nothing selected /
not used / not simulated, or a token the card resolves: ``"ALARM"`` / ``"WARNING"`` (the drive's fault / minor
fault code, SI-T3 Tables 26/27, V7 Tables 10/11), ``"F6-23"`` / ``"F6-24"`` (the register set in that parameter).
Not simulated, so 0: the PG counters (SI-T3/SI-ET3 3, D), the V7 pulse train (5) and analog input FR (C).

:data:`SEL_REF_TABLES`: code -> the reference item REFn sets (``""`` = nothing selected / not used). The SI-T/V7
uses only 4 (terminal outputs): "5 to F Not used. The SI-T/V7 ignores the written data" (V7 Table 4).

tests/wire/test_tables.py reads both against the manual text.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

__all__ = ["SEL_MON_TABLES", "SEL_REF_TABLES"]

_A1000_MON = ("", "U1-05", "U1-09", "", "U1-01", "U1-14", "U1-07", "ALARM", "WARNING",
              "U1-11", "U1-15", "U1-10", "U1-13", "", "F6-23", "F6-24")

#: SEL_MON code (0..F) -> monitor, per card (see the module docstring).
SEL_MON_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "SI-T3": _A1000_MON,  # SI-T3 Table 18 "SEL MON1/2 (3/4, 5/6) Selection Range"
    "SI-ET3": _A1000_MON,  # SI-ET3 Table 22 "SEL_MON Monitor Data Codes"
    # SI-T/V7 Table 5 "SEL MON1/2 Selection Range": 1 is the output frequency (U-02), not the motor speed
    "SI-T/V7": ("", "U-02", "U-08", "", "U-01", "", "U-05", "ALARM", "WARNING", "", "",
                "U-06", "", "", "", ""),
})

_A1000_REF = ("", "torque compensation", "analog output 1", "analog output 2", "terminal outputs",
              "PID setpoint", "pulse output", "V/f gain", "", "control selection", "", "", "", "", "", "")

#: SEL_REF code (0..F) -> reference item, per card (see the module docstring).
SEL_REF_TABLES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "SI-T3": _A1000_REF,  # SI-T3 Table 17 "SEL REF1/2 (3/4, 5/6) Selection Range"
    "SI-ET3": _A1000_REF,  # SI-ET3 Table 21 "SEL_REF Reference Data Codes"
    "SI-T/V7": ("", "", "", "", "terminal outputs", "", "", "", "", "", "", "", "", "", "", ""),  # V7 Table 4
})
