"""The operations a user can perform on a running network, a standalone slave or the impairing proxy, each declared
once (docs/control.md, "The operations").

Every surface is built from :data:`OPERATIONS`: the control endpoints' dispatch (``mlink_sim.aio.control``), the
command line (``mlink-sim control HOST:PORT OP …``, ``param``, ``status``), the HTTP routes and their OpenAPI
document (``mlink_sim.web``), the Python API (:class:`~mlink_sim.aio.run.embed.VirtualNetwork`,
:class:`~mlink_sim.testing.RunningNetwork`, the pytest plugin's fixture) and the config's timeline (``do = NAME``).
Its name, its arguments (:mod:`.args`: kinds, units, ranges), which endpoints serve it, what it answers and how it
is refused are therefore the same on each: ``set-param`` writes the value (PRM_WR) and enters it (CONFIG) wherever
it is asked, ``run`` checks the speed against E1-04 / n011 wherever it is given.

An operation's name is its control request's ``op``, its command-line command and its timeline action; in Python
it is the method of that name with dashes as underscores (``set-param`` -> ``set_param``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from .args import (COUNT, DIRECTION, DURATION, FAULT, FAULT_ACTION, FAULT_KIND, FAULT_NAME, FLAG, HANDLE, HZ,
                   IMPAIRMENT,
                   LINK_DIRECTION, NUMBER, PARAM, PROBABILITY, SINCE, STATION, STATIONS, VALUE, Arg, OpError)
from .specs import fault_of, impairment_of

__all__ = ["Operation", "OPERATIONS", "ENDPOINTS", "operation", "served_by", "parse_request", "request_of",
           "IMPAIR_FIELDS", "FAULT_FIELDS"]

#: Who answers operations: a network (``up`` / ``master --control``: the HTTP API, the Python API and the pytest
#: plugin act on a network through the same operations), a standalone slave (``slave --control``), the impairing
#: proxy (``proxy --control``).
ENDPOINTS = ("network", "slave", "proxy")


@dataclass(frozen=True)
class Operation:
    """One operation (see the module docstring)."""

    name: str
    summary: str  #: one sentence: the command-line help, the HTTP summary, the Python docstring
    args: tuple[Arg, ...] = ()
    endpoints: frozenset[str] = frozenset({"network"})
    acts: bool = True  #: it changes something (logged and traced as an action); False: it only reads
    #: it goes through the station's master (a request such as PRM_RD) and is answered once the station answered
    through_master: bool = False
    http: tuple[str, str] | None = None  #: (method, path) of its HTTP route; None: not on the HTTP API
    timeline: bool = False  #: a config's timeline offers it (``do = NAME``)
    returns: str = ""  #: what a success answers, in words (docs/control.md, the OpenAPI document)
    #: the JSON schema of a success's reply, by its name in the HTTP API's document (``mlink_sim/web/openapi.yaml``:
    #: a response ``StationFigures``, ``Param``, or a schema ``Network``, ``Status``, ``Report``); "": an object
    reply: str = ""
    cites: str = ""  #: the manual tables behind it
    #: a check of the arguments together, after each was read (an impairment's or a fault's own rules); it raises
    #: ``OpError``
    check: Callable[[dict[str, Any]], object] | None = field(default=None, compare=False)

    @property
    def python(self) -> str:
        """Its Python method: ``set_param``."""
        return self.name.replace("-", "_")

    def arg(self, name: str) -> Arg:
        for a in self.args:
            if a.name == name:
                return a
        raise KeyError(name)


_STATION = Arg("station", STATION, "The station.", required=True)
_TARGET = Arg("station", STATIONS, "The station, or 'all' (the default): every station.", default="all")
_NAME = Arg("name", FAULT_NAME, "Its name (default: made from what and where, e.g. loss-21H-1): heal NAME ends it, "
                                "faults lists it.")


def _figures(what: str) -> str:
    return f"{what}; the station's figures as they are now (docs/control.md, \"Station figures\")"


#: The impairment's fields (``mlink_sim.impair.Impairment``), each an argument of ``impair``.
IMPAIR_FIELDS: tuple[Arg, ...] = (
    Arg("loss", PROBABILITY, "Probability per datagram of a loss, 0…1 or '5%'."),
    Arg("burst", NUMBER, "Mean length of a loss burst (Gilbert–Elliott), 1 or more."),
    Arg("delay", DURATION, "Added one-way delay, e.g. 300us."),
    Arg("jitter", DURATION, "Uniform spread ± around the delay, at most the delay."),
    Arg("duplicate", PROBABILITY, "Probability of a duplicated datagram."),
    Arg("reorder", PROBABILITY, "Probability that the next datagram overtakes this one."),
    Arg("corrupt", PROBABILITY, "Probability of a bit flipped after the FCS."),
    Arg("direction", LINK_DIRECTION, "Which way the datagrams are impaired (default both)."),
    Arg("for", DURATION, "How long it lasts (default: until heal)."),
)
#: The faults' fields (``mlink_sim.faults.spec``), each an argument of ``fault``.
FAULT_FIELDS: tuple[Arg, ...] = (
    Arg("for", DURATION, "How long the fault lasts (mains-loss: required)."),
    Arg("count", COUNT, "skip-cycles: transmission cycles the master sends nothing."),
    Arg("kind", FAULT_KIND, "bad-command: which command the master sends."),
    Arg("torque", NUMBER, "load: N·m of constant load torque added."),
    Arg("inertia", NUMBER, "load: kg·m² of inertia added."),
)

OPERATIONS: MappingProxyType[str, Operation] = MappingProxyType({op.name: op for op in (
    # -- seeing -------------------------------------------------------------------------------------------------
    Operation("network", "The network as configured: its name, cycle, stations and timeline.", acts=False,
              http=("GET", "/api/network"),
              reply="Network", returns="name, cycle, cycle_ns, stations (address, name, card, link, frame_size), timeline"),
    Operation("status", "Every station's figures, the elapsed time, the timeline step, host stalls and the latest "
              "events.", (Arg("since", SINCE, "Only the events after this number (0: every event kept).",
                              default=0),),
              endpoints=frozenset({"network", "slave"}), acts=False, http=("GET", "/api/status"),
              reply="Status", returns="network, elapsed_s, step, stalls, stations (figures each), events, seq; a slave: its "
                      "process and its stations' figures"),
    Operation("report", "The report as --report would write it now (docs/report.md).", acts=False,
              http=("GET", "/api/report"), reply="Report", returns="report"),
    Operation("faults", "The impairments and faults in force, by name, each with what it has injected.",
              endpoints=frozenset({"network", "proxy"}), acts=False, http=("GET", "/api/faults"),
              returns="faults (name, kind, given, stations, direction, describe, left_s, injected each), injected "
                      "(per station, since the start)"),
    Operation("recovery", "Each station's latest fault episode: its end and its recovery time.", (_TARGET,),
              acts=False, http=("GET", "/api/recovery"), returns="episodes"),
    Operation("get-param", "Read a drive parameter by name, in its unit (PRM_RD through the master; a standalone "
              "slave reads its own parameter store, as the drive's keypad would).",
              (_STATION, Arg("param", PARAM, "The parameter's name (C1-01, n019).", required=True)),
              endpoints=frozenset({"network", "slave"}), acts=False, through_master=True,
              http=("GET", "/api/stations/{station}/params/{param}"),
              reply="Param", returns="station, param (name, value, unit, raw, register, text)",
              cites="SI-T3 Table 8 PRM_RD, SI-ET3 PRM_RD; parameters: SI-T3 Table 4, SI-ET3 Table 7"),
    # -- steering -----------------------------------------------------------------------------------------------
    Operation("run", "Run the station at a frequency reference: the run command and the reference, sent every "
              "cycle from now on.",
              (_STATION, Arg("hz", HZ, "The frequency reference in Hz, up to E1-04 / n011.", required=True),
               Arg("direction", DIRECTION, "forward (the default) or reverse.", default="forward")),
              http=("POST", "/api/stations/{station}/run"), timeline=True, reply="StationFigures", returns=_figures("station"),
              cites="SI-T3 Table 16 INV_CTL, SI-ET3 Table 20"),
    Operation("speed", "Change the station's frequency reference, its run command as it is.",
              (_STATION, Arg("hz", HZ, "The frequency reference in Hz, up to E1-04 / n011.", required=True)),
              http=("POST", "/api/stations/{station}/speed"), timeline=True, reply="StationFigures", returns=_figures("station"),
              cites="SI-T3 Table 16, SI-ET3 Table 20"),
    Operation("stop", "Take the run command away: the drive stops as its stopping method says (b1-03 / n004).",
              (_STATION,), http=("POST", "/api/stations/{station}/stop"), timeline=True,
              reply="StationFigures", returns=_figures("station")),
    Operation("fault-reset", "Pulse the fault reset of the cyclic command for 50 ms (the run command off).",
              (_STATION,), http=("POST", "/api/stations/{station}/fault-reset"), timeline=True,
              reply="StationFigures", returns=_figures("station"), cites="SI-T3 Table 16 RESET, SI-ET3 Table 20"),
    Operation("ef0", "Set the external fault input of the cyclic command (the drive trips with EF0).",
              (_STATION,), http=("POST", "/api/stations/{station}/ef0"), timeline=True,
              reply="StationFigures", returns=_figures("station"), cites="SI-T3 Table 16 EF0, SI-ET3 Table 20"),
    Operation("alarm-clear", "Clear the station's present faults and alarms (ALM_CLR mode 0); answered once the "
              "station did.", (_STATION,), through_master=True,
              http=("POST", "/api/stations/{station}/alarm-clear"), timeline=True, reply="StationFigures", returns=_figures("station"),
              cites="SI-T3 Table 15 ALM_CLR, SI-ET3 ALM_CLR"),
    Operation("set-param", "Write a drive parameter by name, in its unit, and enter it so that it takes effect "
              "(PRM_WR, then CONFIG; with eeprom CONFIG_MOD 1: saved); the value read back.",
              (_STATION, Arg("param", PARAM, "The parameter's name (C1-01, n019).", required=True),
               Arg("value", VALUE, "The value in the parameter's unit (5.0 for 5.0 s).", required=True),
               Arg("eeprom", FLAG, "Save it too (CONFIG_MOD 1): kept across a power cycle, with the slave's "
                                   "--state-dir.", default=False)),
              endpoints=frozenset({"network", "slave"}), through_master=True,
              http=("PUT", "/api/stations/{station}/params/{param}"), timeline=True,
              reply="Param", returns="station, param (name, value, unit, raw, register, text): the value read back",
              cites="SI-T3 Tables 9 PRM_WR and 12 CONFIG, SI-ET3 PRM_WR and Table 15 CONFIG"),
    Operation("enter", "Enter the parameters written with PRM_WR (CONFIG; with eeprom CONFIG_MOD 1: saved).",
              (_STATION, Arg("eeprom", FLAG, "Save them too (CONFIG_MOD 1).", default=False)),
              through_master=True, http=("POST", "/api/stations/{station}/enter"), timeline=True,
              reply="StationFigures", returns=_figures("station"), cites="SI-T3 Table 12 CONFIG, SI-ET3 Table 15"),
    Operation("disconnect", "DISCONNECT the station: it drops to phase 1 (the master leaves it there).",
              (_STATION,), through_master=True, http=("POST", "/api/stations/{station}/disconnect"),
              timeline=True, reply="StationFigures", returns=_figures("station"), cites="SI-T3 DISCONNECT, SI-ET3 Table 10"),
    Operation("connect", "CONNECT the station again after a DISCONNECT; answered once it is back at its phase.",
              (_STATION,), through_master=True, http=("POST", "/api/stations/{station}/connect"), timeline=True,
              reply="StationFigures", returns=_figures("station"), cites="SI-T3 CONNECT, SI-ET3 Table 10"),
    Operation("kill-slave", "Kill the slave process of the station (mlink-sim up restarts it 0.5 s later).",
              (_STATION,), http=("POST", "/api/stations/{station}/kill-slave"), timeline=True,
              reply="StationFigures", returns=_figures("station")),
    # -- faults -------------------------------------------------------------------------------------------------
    Operation("impair", "Impair the datagrams of a station (or of every station): loss, delay, duplicates, "
              "reordering, corruption (docs/faults.md). Without a name it replaces the station's unnamed impairment; "
              "named, it stacks beside the others (the same name again replaces that one).",
              (_TARGET, Arg("spec", IMPAIRMENT, "The impairment as text (loss=10%,for=2s), instead of its fields."),
               _NAME, *IMPAIR_FIELDS),
              endpoints=frozenset({"network", "proxy"}), http=("POST", "/api/stations/{station}/impair"),
              timeline=True, returns="name, impairment (its fields), describe", check=impairment_of),
    Operation("heal", "End the impairments and faults of a station (or of every station), or only the one of a "
              "name (heal NAME).",
              (_TARGET, Arg("name", FAULT_NAME, "Only the impairment or fault of this name (faults lists them).")),
              endpoints=frozenset({"network", "proxy"}), http=("POST", "/api/stations/{station}/heal"),
              timeline=True, returns="ended (how many), names"),
    Operation("fault", "Start a station, master or drive fault: silence, skip-cycles, freeze-wdt, bad-command, "
              "load, lock-rotor, mains-loss (docs/faults.md); a standalone slave takes the drive faults.",
              (_TARGET, Arg("spec", FAULT, "The fault as text (silence,for=200ms), instead of do and its fields."),
               Arg("do", FAULT_ACTION, "Which fault (silence, load …), with its fields instead of the text.",
                   cli=False),
               _NAME, *FAULT_FIELDS),
              endpoints=frozenset({"network", "slave"}), http=("POST", "/api/stations/{station}/fault"),
              returns="name, fault (its fields), describe, episodes; a standalone slave: handle (for release)",
              check=fault_of, cites="SI-T3 Tables 19–24, V7 Tables 6–9, SI-ET3 COMM_ALM"),
    Operation("release", "End the drive fault a standalone slave answered with HANDLE.",
              (_STATION, Arg("handle", HANDLE, "The fault's handle.", required=True)),
              endpoints=frozenset({"slave"}), returns="released"),
    # -- a slave's process --------------------------------------------------------------------------------------
    Operation("stats", "Every station's snapshot and counters, the process's CPU time and host stalls.",
              (Arg("since", SINCE, "Host stalls after this time (monotonic ns).", default=0),),
              endpoints=frozenset({"slave"}), acts=False,
              returns="pid, wall_s, cpu_s, cpu_pct, stations (snapshots), stalls, stall_totals"),
    Operation("cpu", "The process's CPU time (small at any station count).", endpoints=frozenset({"slave"}),
              acts=False, returns="pid, wall_s, cpu_s, cpu_pct"),
    Operation("drive", "What a station's drive model is doing (its activity: ramp, stall prevention, limits).",
              (_STATION,), endpoints=frozenset({"slave"}), acts=False, returns="activity"),
    Operation("ping", "Is the endpoint there?", endpoints=frozenset(ENDPOINTS), acts=False, returns="nothing"),
)})


def operation(name: str) -> Operation:
    """The operation *name*; ``OpError`` (bad_request) listing them when there is none."""
    try:
        return OPERATIONS[name]
    except KeyError:
        raise OpError("bad_request", f"unknown op {name!r} (known: {', '.join(OPERATIONS)})") from None


def served_by(endpoint: str) -> tuple[Operation, ...]:
    """The operations *endpoint* (one of :data:`ENDPOINTS`) answers, in the table's order."""
    return tuple(op for op in OPERATIONS.values() if endpoint in op.endpoints)


#: Fields every request may carry besides its arguments: the endpoint's (``op``, ``id``: a repeated request acts
#: once; ``token``).
_ENVELOPE = frozenset({"op", "id", "token"})


def parse_request(op: Operation, request: dict[str, Any]) -> dict[str, Any]:
    """The arguments of *request* (a control request's JSON object, or keyword arguments) as *op* takes them, by
    their Python names; ``OpError`` (bad_request) for a field *op* does not take or a required one missing, or the
    argument's own refusal."""
    names = {a.name: a for a in op.args}
    unknown = sorted(k for k in request if k not in names and k not in _ENVELOPE)
    if unknown:
        takes = ", ".join(names) or "no arguments"
        raise OpError("bad_request", f"{op.name}: unknown field(s) {', '.join(unknown)} (it takes: {takes})")
    out: dict[str, Any] = {}
    for arg in op.args:
        value = request.get(arg.name)
        if value is None:
            if arg.required:
                example = arg.kind.schema.get("examples", [None])[0]
                hint = f", e.g. {arg.name} = {example!r}" if example is not None else ""
                raise OpError("bad_request", f"{op.name}: {arg.name} is missing ({arg.kind.describe}{hint})")
            value = arg.default
            out[arg.python] = None if value is None else arg.read(value)
        else:
            out[arg.python] = arg.read(value)
    if op.check is not None:
        op.check(out)
    return out


def request_of(name: str, /, **args: Any) -> dict[str, Any]:
    """The control request of operation *name* with *args* given by their Python names (``for_``): ``op`` and the
    fields by their request names, None values left out (their defaults apply)."""
    op = operation(name)
    by_python = {a.python: a.name for a in op.args}
    unknown = sorted(k for k in args if k not in by_python)
    if unknown:
        raise OpError("bad_request", f"{name}: unknown argument(s) {', '.join(unknown)} (it takes: "
                                     f"{', '.join(by_python) or 'none'})")
    return {"op": name, **{by_python[k]: v for k, v in args.items() if v is not None}}
