"""Station, master and drive faults on purpose, to test how a master and its stations meet them (docs/faults.md).

* :mod:`.spec` — what each fault is, validated (``silence``, ``skip-cycles``, ``freeze-wdt``, ``bad-command``,
  ``load``, ``lock-rotor``, ``mains-loss``);
* :mod:`.stage` — the master-side faults, a sans-I/O stage between a master core and its transport;
* :mod:`.plant` — the drive faults, applied to a station's drive model on the slave side;
* :mod:`.recovery` — recovery times, measured from each fault's end.
"""

from .recovery import Episode, RecoveryLog
from .spec import (
    BAD_COMMAND_KINDS, FAULT_ACTIONS, MASTER_FAULTS, PLANT_FAULTS, BadCommand, FaultError, FaultSpec, FreezeWdt,
    LoadStep, LockRotor, MainsLoss, MasterFault, PlantFault, Silence, SkipCycles, fault_from_fields,
)
from .stage import FaultStage, StationTraits

__all__ = [
    "BAD_COMMAND_KINDS", "FAULT_ACTIONS", "MASTER_FAULTS", "PLANT_FAULTS", "BadCommand", "Episode", "FaultError",
    "FaultSpec", "FaultStage", "FreezeWdt", "LoadStep", "LockRotor", "MainsLoss", "MasterFault",
    "PlantFault", "RecoveryLog", "Silence", "SkipCycles", "StationTraits", "fault_from_fields",
]
