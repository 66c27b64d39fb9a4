"""Station, master and drive faults from a test (docs/faults.md, "From a test"; the fixture: docs/ci.md): the methods
of the ``mlink_network`` fixture on both clocks.

    net.silence(0x21, for_=0.2)                       # answers dropped for 200 ms
    net.skip_cycles(0x21, count=3)                    # three transmission cycles without a command
    net.freeze_wdt(0x23, for_="50ms")                 # the WDT count stops
    net.bad_command(0x21, "data-size")                # A.94 / CMD_ALM 9H
    net.load(0x21, torque=5.0, for_=1.0)              # a load step of 5 N·m for a second
    net.lock_rotor(0x22)                              # the shaft jams: oC (running) or oL1
    net.mains_loss(0x23, for_=0.3)                    # the DC bus sags: Uv1
    ep = net.fault_episode(0x21)                      # its end, recovery time (ns) …
    net.check("station[0x21].recovery.max < 50ms")

Durations are seconds (a number) or a string with a unit. Bad values raise ``ValueError`` (a
:class:`~mlink_sim.faults.FaultError`) in the test, before anything reaches the network. Each method returns the
fault's episode as a :class:`FaultEpisode` (as of when it was applied; :meth:`FaultMethods.fault_episode` later).
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..faults import Episode, fault_from_fields

__all__ = ["FaultMethods", "FaultEpisode", "episode_dict"]


@dataclass(frozen=True)
class FaultEpisode:
    """One fault of one station as the master's fault stage recorded it (times: the run's clock, ns)."""

    station: int
    what: str
    start_ns: int
    end_ns: int | None
    recovered_ns: int | None
    recovery_ns: int | None  #: from the fault's end to phase 3 with no alarm (None: not yet, or not ended)
    notes: tuple[str, ...] = ()  #: e.g. "answered A.94 DATA_SETTING_WARNING"
    name: str = ""  #: the fault's name (``heal(name=…)`` ends it; docs/faults.md, "Names")
    injected: Mapping[str, int] = field(default_factory=dict)  #: what it did to the datagrams while in force


def episode_dict(ep: Episode | None) -> dict[str, Any] | None:
    """An episode as JSON (what the host process sends back)."""
    return None if ep is None else ep.as_dict()


def _episode(d: dict[str, Any] | None) -> FaultEpisode | None:
    return None if d is None else FaultEpisode(**{**d, "notes": tuple(d.get("notes", ()))})


class FaultMethods(abc.ABC):
    """The fault methods over both clocks, each one the ``fault`` operation of one kind (the network class's
    :meth:`fault`, :class:`~mlink_sim.operations.NetworkOperations`)."""

    fault: Any  #: the ``fault`` operation of the network class

    @abc.abstractmethod
    def _fault_episode(self, station: int) -> dict[str, Any] | None:
        """The station's latest fault episode as JSON, or None."""

    def _apply(self, station: int, action: str, **fields: Any) -> FaultEpisode:
        fault_from_fields(action, {("for" if k == "for_" else k): v for k, v in fields.items() if v is not None})
        reply = self.fault(station, do=action, **fields)  # a bad value raised above, in the test
        episode = _episode(next(iter(reply["episodes"].values())))
        assert episode is not None
        return episode

    def silence(self, station: int, for_: float | str) -> FaultEpisode:
        """The station answers nothing for *for_* (its responses are dropped on their way to the master)."""
        return self._apply(station, "silence", for_=for_)

    def skip_cycles(self, station: int, count: int) -> FaultEpisode:
        """The master sends *station* nothing in the next *count* transmission cycles."""
        return self._apply(station, "skip-cycles", count=count)

    def freeze_wdt(self, station: int, for_: float | str) -> FaultEpisode:
        """The master's WDT count in the commands to *station* stops advancing for *for_*."""
        return self._apply(station, "freeze-wdt", for_=for_)

    def bad_command(self, station: int, kind: str) -> FaultEpisode:
        """One command *station* must refuse: ``"phase"``, ``"combination"`` or ``"data-size"``."""
        return self._apply(station, "bad-command", kind=kind)

    def load(self, station: int, *, torque: float | None = None, inertia: float | None = None,
             for_: float | str | None = None) -> FaultEpisode:
        """A load step: *torque* N·m and/or *inertia* kg·m² added to the shaft (for *for_*, else for good)."""
        return self._apply(station, "load", torque=torque, inertia=inertia, for_=for_)

    def lock_rotor(self, station: int, for_: float | str | None = None) -> FaultEpisode:
        """The shaft jams (released after *for_*, else never)."""
        return self._apply(station, "lock-rotor", for_=for_)

    def mains_loss(self, station: int, for_: float | str) -> FaultEpisode:
        """The drive's mains are gone for *for_*."""
        return self._apply(station, "mains-loss", for_=for_)

    def fault_episode(self, station: int) -> FaultEpisode | None:
        """The latest fault of *station* as of now (its recovery time once it has recovered)."""
        return _episode(self._fault_episode(station))
