"""Drive status as the network sees it, and its two wire layouts.

* MECHATROLINK-II STATUS field: SI-T3 "STATUS Field" (section 8, Status) and SI-T/V7 7.3
  "STATUS Field" (bits E/F not used on the V7).
* MECHATROLINK-III INVCMD_STAT: SI-ET3 section 9, "INVCMD_STAT" bit table.
"""

from __future__ import annotations

from dataclasses import dataclass

from .faults import Fault

__all__ = ["DriveStatus", "ml2_status_bits", "ml3_invcmd_stat_bits"]


@dataclass(frozen=True, slots=True)
class DriveStatus:
    """Snapshot of the drive's status signals."""

    running: bool  # RUNX: run command active or output still on (decelerating)
    reverse: bool  # REV: output (or run direction at 0 Hz) reverse
    zero_speed: bool  # 0SP: output frequency below E1-09 / n016, or output off
    speed_agree: bool  # AGREE: |fout - fref| <= L4-02 while running (V7: 2 Hz)
    user_speed_agree: bool  # |fout| within L4-02 of L4-01 (A1000 "user-set speed agree")
    ready: bool  # INV_READY: power on, no fault, no oPE
    faulted: bool  # ALM
    minor_fault: bool  # WARNG (drive side)
    baseblock: bool  # output off (STATUS BB OFF = not baseblock)
    main_power_on: bool  # PON: mains on and DC bus above the Uv level
    ope: bool  # oPE fault (CONFIG found inconsistent settings)
    fault_reset_input: bool  # RESET: fault reset signal being input
    remote: bool  # REMOTE: run command / reference from the option card
    motor2: bool  # SEL_M: motor 2 selected (A1000 H1 = 16H)
    torque_limited: bool  # torque held at the network torque limit or torque reference
    fault: Fault | None = None  # active fault (trip)
    minor: Fault | None = None  # minor fault with the lowest code (SI-T3 / SI-T/V7 "Drive warning")
    minors: frozenset[Fault] = frozenset()
    ope_code: str | None = None  # e.g. "oPE10"
    power_loss_recovery: bool = False  # UV_R: 0 = recovery after power loss (not modelled)
    stall_prevention: bool = False  # ramp held by stall prevention (accel or decel)


def ml2_status_bits(st: DriveStatus, *, cmdrdy: bool = True, bits_e_f: bool = True) -> int:
    """MECHATROLINK-II STATUS word (SI-T3 / SI-T/V7 STATUS field).

    ALM/WARNG reflect the drive only (communication alarms are the card's); ALM is not reported
    while the fault reset signal is on (SI-T3 Table 16 note <2>).  ``bits_e_f`` False: bits E, F are unused (the
    SI-T/V7, V7 §7.3; ``CardProfile.status_bits_e_f``).
    """
    w = 0
    if st.faulted and not st.fault_reset_input:
        w |= 1 << 0
    if st.minor_fault:
        w |= 1 << 1
    if cmdrdy:
        w |= 1 << 2
    if not st.baseblock:
        w |= 1 << 3
    if st.main_power_on:
        w |= 1 << 4
    if st.running:
        w |= 1 << 5
    if st.zero_speed:
        w |= 1 << 6
    if st.reverse:
        w |= 1 << 7
    if st.fault_reset_input:
        w |= 1 << 8
    if st.speed_agree:
        w |= 1 << 9
    if st.ready:
        w |= 1 << 10
    if st.ope:
        w |= 1 << 11
    if st.power_loss_recovery:
        w |= 1 << 12
    if st.remote:
        w |= 1 << 13
    if st.motor2 and bits_e_f:
        w |= 1 << 14
    return w


def ml3_invcmd_stat_bits(st: DriveStatus) -> int:
    """MECHATROLINK-III INVCMD_STAT bits 0..13 (SI-ET3); bits 24/25 (SEL_MON status) are the card's."""
    w = 0
    if st.running and not st.reverse:
        w |= 1 << 0
    if st.running and st.reverse:
        w |= 1 << 1
    if not st.baseblock:
        w |= 1 << 2
    if st.main_power_on:
        w |= 1 << 3
    if st.zero_speed:
        w |= 1 << 4
    if st.speed_agree:
        w |= 1 << 5
    if st.ready:
        w |= 1 << 6
    if st.ope:
        w |= 1 << 7
    if st.fault_reset_input:
        w |= 1 << 9
    if st.power_loss_recovery:
        w |= 1 << 10
    if st.remote:
        w |= 1 << 11
    if st.motor2:
        w |= 1 << 12
    return w
