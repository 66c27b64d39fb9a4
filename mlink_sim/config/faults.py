"""Validation of the timeline's fault steps and recovery checks (docs/faults.md): which fields each fault takes, and
what a station must have for a fault to make sense (sub-commands for a combination error …). Every message names
the field and what was expected; the loader prefixes the step (``timeline[3]``) and the CLI exits 2."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ..faults.spec import FAULT_ACTIONS, FaultError, fault_from_fields

__all__ = ["check_fault_step", "check_fault_targets", "fault_end_ns", "step_fault"]


def _field_values(step: Any) -> dict[str, Any]:
    return {"for": step.for_, "count": step.count, "kind": step.kind, "torque": step.torque,
            "inertia": step.inertia}


def check_fault_step(step: Any) -> None:
    """A fault action's values valid for that fault (:func:`~mlink_sim.faults.spec.fault_from_fields`: the fields of
    another fault are refused there; the actions' fields were read by the operations table); ``within`` with
    ``expect = "recovered"`` only (and needed)."""
    values = _field_values(step)
    if step.do in FAULT_ACTIONS:
        try:
            fault_from_fields(step.do, values)
        except FaultError as exc:
            raise ValueError(str(exc)) from None
    if step.expect == "recovered":
        if step.within is None:
            raise ValueError("'expect = \"recovered\"' needs within, e.g. within = \"50ms\" (the longest recovery)")
        if step.within <= 0:
            raise ValueError("within: expected a duration above 0")
    elif step.within is not None:
        raise ValueError("within: only expect = \"recovered\" takes it")


def check_fault_targets(step: Any, stations: Sequence[Any], where: str) -> None:
    """What the targeted *stations* need for *step*'s fault (called once their defaults are filled in)."""
    if step.do == "bad-command":
        for st in stations:
            label = f"station {st.address:02X}H ({st.card}, {st.frame_size}-byte)"
            if step.kind == "combination" and not st.subcmd:
                raise ValueError(f"{where}.kind: a combination error pairs a main command with a sub-command "
                                 f"(SI-T3 Table 7, SI-ET3 Table 13), but {label} has subcmd = false")
            if step.kind == "data-size" and st.profile.prm_as_subcommand and st.frame_size == 32 and not st.subcmd:
                raise ValueError(f"{where}.kind: a 32-byte {st.profile.label} takes PRM_RD only as a sub-command "
                                 f"({st.profile.sources['prm_as_subcommand']}), and {label} has subcmd = false")
    if step.do == "load" and step.torque:
        for st in stations:
            if st.load.kind == "fan":
                raise ValueError(f"{where}.torque: station {st.address:02X}H has a fan load, and the model carries "
                                 f"one load-torque law per shaft (docs/drive-model.md §4): step its inertia instead, "
                                 f"or give it a constant or friction load")


def step_fault(step: Any) -> Any:
    """The :mod:`mlink_sim.faults.spec` value of a fault step (validated when the config was loaded)."""
    return fault_from_fields(step.do, {"for_ns": step.for_, "count": step.count, "kind": step.kind,
                                       "torque": step.torque, "inertia": step.inertia})


def fault_end_ns(step: Any) -> int:
    """When the step is over: ``at`` plus a station, master or drive fault's ``for`` and a recovery check's
    ``within`` (an ``impair`` step's ``for`` does not extend the run: ``heal`` or the run's end cut it short)."""
    return step.at + (step.for_ or 0 if step.do in FAULT_ACTIONS else 0) + (step.within or 0)
