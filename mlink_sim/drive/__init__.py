"""VFD dynamics model behind the simulated option cards (pure; stepped with explicit time).

See docs/drive-model.md for the model, its equations, parameters and limits.
"""

from .drive import Drive, DriveCommand
from .faults import (
    ET3_FAULT_CODES,
    ET3_MINOR_CODES,
    SI_T3_FAULT_CODES,
    SI_T3_MINOR_CODES,
    V7_FAULT_CODES,
    V7_WARNING_CODES,
    Fault,
    fault_code,
    minor_code,
)
from .monitors import SEL_MON_TABLES, hz_to_ref, ref_to_hz
from .motor import LoadSpec, vf_voltage
from .settings import OPTIONAL_DEFAULTS, DriveSettings, Family, StopMethod, required_params
from .status import DriveStatus, ml2_status_bits, ml3_invcmd_stat_bits

__all__ = [
    "Drive",
    "DriveCommand",
    "DriveSettings",
    "DriveStatus",
    "ET3_FAULT_CODES",
    "ET3_MINOR_CODES",
    "Family",
    "Fault",
    "LoadSpec",
    "OPTIONAL_DEFAULTS",
    "SEL_MON_TABLES",
    "SI_T3_FAULT_CODES",
    "SI_T3_MINOR_CODES",
    "StopMethod",
    "V7_FAULT_CODES",
    "V7_WARNING_CODES",
    "fault_code",
    "hz_to_ref",
    "minor_code",
    "ref_to_hz",
    "ml2_status_bits",
    "ml3_invcmd_stat_bits",
    "required_params",
    "vf_voltage",
]
