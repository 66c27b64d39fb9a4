"""The network's operations as Python methods: :class:`NetworkOperations`, which the embedded virtual network
(:class:`~mlink_sim.aio.run.embed.VirtualNetwork`), the test harness (:class:`~mlink_sim.testing.RunningNetwork`)
and the pytest plugin's fixture all derive from, each performing a request its own way (:meth:`_perform`: on the
virtual clock in this process, or in the network's host process).

One method per operation a network serves (:func:`~.table.served_by`), named as the operation with dashes as
underscores and taking its arguments by their Python names (``set-param`` -> ``set_param(station, param, value,
eeprom=False)``); its docstring is the operation's summary. tests/operations/test_methods.py holds the methods and the
table to each other. An operation refuses with :class:`~.args.OpError` (a ``ValueError`` with its ``kind``), the
same message every surface gives.

The bare protocol commands (``prm_rd``, ``prm_wr``, ``send_config``, ``alm_clr``, ``set_control`` …) stay on the
surfaces beside these, under their protocol names, for tests of a master's own handling: ``prm_wr`` writes and does
not enter (CONFIG is ``send_config``), where ``set_param`` writes and enters.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from ..master.types import ParamValue
from .table import OPERATIONS

__all__ = ["NetworkOperations", "param_value"]

Station = int | str  #: a station address: 0x21, "21H", "0x21" or 33
F = TypeVar("F", bound=Callable[..., Any])


def _summary(name: str) -> Callable[[F], F]:
    """The method's docstring: the operation's summary, and what the method answers."""
    def apply(fn: F) -> F:
        op = OPERATIONS[name]
        fn.__doc__ = f"{op.summary}\n\n{(fn.__doc__ or '').strip()}".strip()
        return fn

    return apply


def param_value(reply: dict[str, Any]) -> ParamValue:
    """The ``param`` of a ``get-param`` / ``set-param`` reply as a :class:`~mlink_sim.master.ParamValue`."""
    p = reply["param"]
    return ParamValue(p["name"], float(p["value"]), p["unit"], int(p["raw"]), int(str(p["register"]).rstrip("H"), 16),
                      p["text"])


class NetworkOperations:
    """The operations of a network (see the module docstring); a subclass implements :meth:`_perform`."""

    def _perform(self, op: str, **args: Any) -> dict[str, Any]:
        """Perform *op* with *args* (by their Python names), as the control endpoint would: its reply's fields,
        :class:`~.args.OpError` when it is refused."""
        raise NotImplementedError

    @_summary("network")
    def network(self) -> dict[str, Any]:
        return self._perform("network")

    @_summary("status")
    def status(self, since: int = 0) -> dict[str, Any]:
        return self._perform("status", since=since)

    @_summary("report")
    def report(self) -> dict[str, Any]:
        """Returns the report document."""
        return dict(self._perform("report")["report"])

    @_summary("faults")
    def faults(self) -> dict[str, Any]:
        return self._perform("faults")

    @_summary("recovery")
    def recovery(self, station: Station = "all") -> dict[str, Any]:
        return self._perform("recovery", station=station)

    @_summary("get-param")
    def get_param(self, station: Station, param: str) -> ParamValue:
        """Returns the value as a :class:`~mlink_sim.master.ParamValue` (a float in the parameter's unit)."""
        return param_value(self._perform("get-param", station=station, param=param))

    @_summary("run")
    def run(self, station: Station, hz: float, direction: str = "forward") -> dict[str, Any]:
        return self._perform("run", station=station, hz=hz, direction=direction)

    @_summary("speed")
    def speed(self, station: Station, hz: float) -> dict[str, Any]:
        return self._perform("speed", station=station, hz=hz)

    @_summary("stop")
    def stop(self, station: Station) -> dict[str, Any]:
        return self._perform("stop", station=station)

    @_summary("fault-reset")
    def fault_reset(self, station: Station) -> dict[str, Any]:
        return self._perform("fault-reset", station=station)

    @_summary("ef0")
    def ef0(self, station: Station) -> dict[str, Any]:
        return self._perform("ef0", station=station)

    @_summary("alarm-clear")
    def alarm_clear(self, station: Station) -> dict[str, Any]:
        return self._perform("alarm-clear", station=station)

    @_summary("set-param")
    def set_param(self, station: Station, param: str, value: float | int | str, eeprom: bool = False) -> ParamValue:
        """Returns the value read back as a :class:`~mlink_sim.master.ParamValue`."""
        return param_value(self._perform("set-param", station=station, param=param, value=value, eeprom=eeprom))

    @_summary("enter")
    def enter(self, station: Station, eeprom: bool = False) -> dict[str, Any]:
        return self._perform("enter", station=station, eeprom=eeprom)

    @_summary("disconnect")
    def disconnect(self, station: Station) -> dict[str, Any]:
        return self._perform("disconnect", station=station)

    @_summary("connect")
    def connect(self, station: Station) -> dict[str, Any]:
        return self._perform("connect", station=station)

    @_summary("kill-slave")
    def kill_slave(self, station: Station) -> dict[str, Any]:
        return self._perform("kill-slave", station=station)

    @_summary("impair")
    def impair(self, station: Station = "all", spec: str | None = None, *, name: str | None = None,
               loss: float | str | None = None, burst: float | None = None, delay: float | str | None = None, jitter: float | str | None = None,
               duplicate: float | str | None = None, reorder: float | str | None = None,
               corrupt: float | str | None = None, direction: str | None = None,
               for_: float | str | None = None) -> dict[str, Any]:
        """Give the impairment as text (``impair(0x21, "loss=10%,for=2s")``) or as its fields (``impair(0x21,
        loss=0.1, for_=2.0)``; durations: a number of seconds or text with a unit). The reply's ``name`` is what
        :meth:`heal` takes."""
        return self._perform("impair", station=station, spec=spec, name=name, loss=loss, burst=burst, delay=delay,
                             jitter=jitter, duplicate=duplicate, reorder=reorder, corrupt=corrupt,
                             direction=direction, for_=for_)

    @_summary("heal")
    def heal(self, station: Station = "all", name: str | None = None) -> int:
        """Returns how many impairments and faults ended (``heal(name="loss-21H-1")``: that one)."""
        return int(self._perform("heal", station=station, name=name)["ended"])

    @_summary("fault")
    def fault(self, station: Station = "all", spec: str | None = None, *, do: str | None = None,
              name: str | None = None, for_: float | str | None = None, count: int | None = None, kind: str | None = None,
              torque: float | None = None, inertia: float | None = None) -> dict[str, Any]:
        """Give the fault as text (``fault(0x21, "silence,for=200ms")``) or as ``do`` and its fields (``fault(0x21,
        do="load", torque=5.0, for_=1.0)``). The reply's ``episodes`` hold each station's episode."""
        return self._perform("fault", station=station, spec=spec, do=do, name=name, for_=for_, count=count, kind=kind,
                             torque=torque, inertia=inertia)
