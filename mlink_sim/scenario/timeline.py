"""The timeline of a config as a state machine on explicit time: which steps are due at ``now``, what each action
asks of the network, and the checks' results.

An action step is one or more operations of :mod:`mlink_sim.operations` with their arguments
(:meth:`Timeline.requests`): the timeline acts on a network exactly as a control request, the command line, the
HTTP API or the Python API do (``do = "set-param"`` is the ``set-param`` operation: PRM_WR, then CONFIG). A check
is judged from the master's view (:func:`~.checks.judge`), or, for the fault checks, waited for
(:mod:`.faultchecks`). The driver that sleeps, performs and reads is the control plane's
(:mod:`mlink_sim.aio.control.timeline`); this module never reads a clock.

Speeds are given in Hz and converted with each station's own reference units (o1-03 / n035) by the operations, so
a scenario reads the same whatever the drive's parameters are.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ..config import Config, TimelineStep
from ..operations import operation, parse_request
from .checks import CheckResult, with_stalls
from .values import station_values

__all__ = ["Timeline", "Request"]

#: Operations one request serves for every station (``station = "all"`` is one fault on every path).
_NETWORK_WIDE = frozenset({"impair", "heal", "fault"})


@dataclass(frozen=True)
class Request:
    """One operation an action step performs: ``op`` with its arguments by their Python names, as
    :func:`~mlink_sim.operations.parse_request` gives them."""

    step: TimelineStep
    op: str
    args: dict[str, Any]


class Timeline:
    """The timeline of *config*: :meth:`start` at the timeline's 0 s, then :meth:`due` whenever
    :meth:`next_deadline` has come (times in ns on the run's clock)."""

    def __init__(self, config: Config) -> None:
        self.config = config
        self.steps: list[TimelineStep] = sorted(config.timeline, key=lambda s: s.at)
        self.started = 0  #: steps begun so far, in order of time (``steps[:started]``)
        self.results: list[CheckResult] = []  #: the checks judged so far
        self.action_errors: list[str] = []  #: an action that failed, one line each
        self.t0_ns: int | None = None  #: the run clock's time of the timeline's 0 s, once started
        self._values: dict[int, dict[str, int]] = {}  # values_of(), read when first needed

    # -- time ---------------------------------------------------------------------------------------------------

    def start(self, now_ns: int) -> None:
        """The timeline's 0 s is *now_ns*."""
        self.t0_ns = now_ns

    def next_deadline(self) -> int | None:
        """When the next step is due (None: not started, or every step begun)."""
        if self.t0_ns is None or self.started >= len(self.steps):
            return None
        return self.t0_ns + self.steps[self.started].at

    def due(self, now_ns: int) -> list[TimelineStep]:
        """The steps whose time has come by *now_ns*, in order; each is begun (counted in :attr:`started`)."""
        out = []
        while (deadline := self.next_deadline()) is not None and deadline <= now_ns:
            out.append(self.steps[self.started])
            self.started += 1
        return out

    @property
    def current(self) -> TimelineStep | None:
        """The step begun last (None before the first)."""
        return self.steps[self.started - 1] if self.started else None

    def not_run(self) -> list[TimelineStep]:
        """The steps that never began (the run ended first: --duration, a signal)."""
        return self.steps[self.started:]

    # -- actions ------------------------------------------------------------------------------------------------

    def targets(self, step: TimelineStep) -> list[int]:
        """The stations *step* is about, in the config's order."""
        return [st.address for st in self.config.station] if step.station == "all" else [int(step.station)]

    def requests(self, step: TimelineStep) -> list[Request]:
        """The operations the action *step* performs: one per station it names, or one for the whole network for
        the faults and impairments (``station = "all"``: every station's path)."""
        op = operation(step.operation)
        if op.name in _NETWORK_WIDE:
            stations: list[Any] = ["all" if step.station == "all" else step.station]
        else:
            stations = list(self.targets(step))
        return [Request(step, op.name, parse_request(op, step.request(s))) for s in stations]

    def failed(self, step: TimelineStep, error: BaseException) -> str:
        """Record that an action of *step* failed; the line the run's problems and summary show."""
        line = f"{step.describe}: {error}"
        self.action_errors.append(line)
        return line

    def entered(self, address: int, name: str, raw: int) -> None:
        """A ``set-param`` step's value took effect on *address* (what :meth:`values_of` answers from then on)."""
        self.values_of(address)[name] = raw

    def values_of(self, address: int) -> dict[str, int]:
        """*address*'s parameter values in effect (raw, by name): the config's on the family defaults, then each
        ``set-param`` step's. Built when first needed (a failed check, a set-param step), not for every station when
        the timeline starts: the loop keeps time by then."""
        values = self._values.get(address)
        if values is None:
            values = self._values[address] = station_values(self.config.station_by_address(address))
        return values

    # -- checks -------------------------------------------------------------------------------------------------

    def record(self, result: CheckResult) -> None:
        """A check's result, as it was judged."""
        self.results.append(result)

    def explained(self, result: CheckResult, cause: str | None) -> CheckResult | None:
        """*result* (already recorded) with its *cause*; the new result, None when it was not recorded."""
        for i, r in enumerate(self.results):
            if r is result:
                self.results[i] = dataclasses.replace(result, cause=cause or None)
                return self.results[i]
        return None

    def results_naming_stalls(self, stalls: Any) -> list[CheckResult]:
        """The checks so far, each failed one naming the host stalls of the three seconds before it
        (docs/timing.md, "Host stalls"); *stalls* is the run's ``metrics.stalls.StallLog``."""
        t0 = self.t0_ns
        return list(self.results) if t0 is None else [with_stalls(c, stalls, t0) for c in self.results]
