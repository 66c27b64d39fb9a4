"""Network impairments as a sans-I/O layer between the cores and the transport (docs/faults.md)."""

from .layer import ALL, IMPAIR, Fault, ImpairmentLayer, impairment_kind, impairment_stages
from .names import Names, check_name
from .spec import (DIRECTIONS, Direction, ImpairError, Impairment, as_impairment, parse_impair_text,
                   parse_probability, target_station)
from .stages import ORDER, Corrupt, Delay, Duplicate, Loss, PathState, Reorder, Stage

__all__ = ["ALL", "IMPAIR", "Fault", "ImpairmentLayer", "Names", "PathState", "check_name", "impairment_kind",
           "impairment_stages", "DIRECTIONS", "Direction", "ImpairError", "Impairment", "as_impairment",
           "target_station", "parse_impair_text", "parse_probability", "ORDER", "Corrupt", "Delay", "Duplicate",
           "Loss", "Reorder", "Stage"]
