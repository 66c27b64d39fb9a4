"""The impairment and the fault an ``impair`` / ``fault`` request names, as text (``"loss=10%,for=2s"``,
``"silence,for=200ms"``) or as fields (``loss = 0.1``, ``do = "silence"`` and ``for``): one reading for the control
endpoint, the command line, the HTTP API, the Python API and the timeline."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..faults.spec import FaultError, FaultSpec, fault_from_fields
from ..impair.spec import ImpairError, Impairment, as_impairment
from .args import OpError

__all__ = ["impairment_of", "fault_of", "parse_fault_text"]

_IMPAIR_FIELDS = ("loss", "burst", "delay", "jitter", "duplicate", "reorder", "corrupt", "direction", "for_")
_FAULT_FIELDS = ("for_", "count", "kind", "torque", "inertia")


def impairment_of(args: Mapping[str, Any]) -> Impairment:
    """The :class:`~mlink_sim.impair.Impairment` of ``impair``'s arguments (by their Python names): its text
    (``spec``) or its fields, not both; ``OpError`` (bad_request) naming the field otherwise."""
    fields = {name: args[name] for name in _IMPAIR_FIELDS if args.get(name) is not None}
    try:
        return as_impairment(args.get("spec"), fields)
    except ImpairError as exc:
        text = str(exc)
        raise OpError("bad_request", text if text.startswith("impair:") else f"impair: {text}") from None


def parse_fault_text(text: str) -> tuple[str, dict[str, Any]]:
    """``"silence,for=200ms"`` / ``"bad-command,kind=phase"`` / ``"load,torque=5,for=1s"`` -> (action, fields), the
    values as strings or numbers (:func:`~mlink_sim.faults.fault_from_fields` checks them)."""
    action, *rest = [part.strip() for part in text.split(",") if part.strip()] or [""]
    fields: dict[str, Any] = {}
    for part in rest:
        name, sep, value = part.partition("=")
        if not sep:
            raise FaultError(f"{part}: expected NAME=VALUE after the fault's name, e.g. 'silence,for=200ms'")
        try:
            fields[name.strip()] = int(value) if value.strip().lstrip("-").isdigit() else float(value)
        except ValueError:
            fields[name.strip()] = value.strip()
    return action, fields


def fault_of(args: Mapping[str, Any]) -> FaultSpec:
    """The fault of ``fault``'s arguments (by their Python names): its text (``spec``), or ``do`` and its fields;
    ``OpError`` (bad_request) naming the field otherwise."""
    fields = {("for" if name == "for_" else name): args[name] for name in _FAULT_FIELDS if args.get(name) is not None}
    try:
        text = args.get("spec")
        if text is not None:
            if args.get("do") is not None:
                raise FaultError("give the fault as text or as do and its fields, not both")
            action, parsed = parse_fault_text(text)
            fields = {**parsed, **fields}
        else:
            action = args.get("do") or ""
            if not action:
                raise FaultError("give the fault, e.g. 'silence,for=200ms' (or do = \"silence\" and for)")
        return fault_from_fields(action, fields)
    except FaultError as exc:
        raise OpError("bad_request", f"fault: {exc}") from None
