"""The figures of one station of a running network as one flat, JSON-safe dict: the one definition the control
endpoint's ``status`` answers with, the traces record and the web page shows (docs/control.md, "Station figures").

    figures = NetworkFigures(config)                       # once: per-station constants (about 1 ms a station)
    rows = figures.stations(session.net, session.metrics)  # per call: views, a few RTT percentiles, dicts
    rows[0]["output_hz"], rows[0]["leds"]                  # 30.0, {"RUN": "on", "ERR": "off", …}

Where each figure comes from (:class:`StationFigures`):

* the master's view of the station (:class:`~mlink_sim.master.StationView`, the latest INV_CTL response):
  ``phase``, ``connected``, ``alarm`` and ``warnings``, ``running`` / ``direction`` (STATUS RUNX/REV, ML-III
  INVCMD_STAT FORWARD/REVERSE), ``output_hz`` (output frequency in o1-03 / n035 units), ``output_current_a`` (the
  response's output current, 0.1 A), ``missed`` / ``late`` (answers missing or late, since the start);
* the response's monitors MON1/MON2 as the master's SEL_MON selects them (SI-T3 Table 18, SI-ET3 Table 22, SI-T/V7
  Table 5; the master's default 41H: MON1 motor speed, MON2 frequency reference): ``reference_hz`` (U1-01 / U-01, a
  magnitude: the run command gives the direction), ``motor_speed_rpm`` (U1-05, signed, o1-03 units through the
  motor's pole pairs), ``dc_bus_v`` (U1-07 / U-05);
* the slave's own snapshot where the run hosts the slaves (``mlink-sim up``: the workers' ``stats``, the virtual
  clock's card cores; up to a second old): the figures the monitors do not carry (with the default SEL_MON:
  ``dc_bus_v``; on an SI-T/V7, which has no motor-speed monitor, ``motor_speed_rpm``), the names of the warnings the
  response flags, and the LEDs of a station the master does not reach (an address error blinks ERR); else null;
* the LEDs of a station that answers: the card's LED table read from what the master sees (SI-T3 Table 3, SI-ET3
  Table 4, SI-T/V7 §3.3 "LED Indicators"), as fresh as the latest response: RUN / R/E lit while the station answers,
  ERR lit for a communication alarm, R/E red for an alarm or a command error, CON lit while connected, TX / RX / LK1
  lit while datagrams flow (:data:`~mlink_sim.cards.base.LED_WINDOW_NS`, as the card counts them); LK2 unlit (one
  simulated port);
* the run's RTT histogram (:class:`RttPercentiles`): ``rtt_p50_us``, ``rtt_p99_us``, a few stations refreshed per call;
  the latest round trip, ``rtt_us``, from the master's view;
* the drive's regulation (``regulation``: the states of :data:`mlink_sim.drive.activity.REGULATION` its drive was in,
  stall prevention and the torque limit), from the slave's snapshot (``"regulation"``: the code of
  :meth:`mlink_sim.drive.Drive.regulation` over the :data:`REGULATION_WINDOW_NS` before it); null without one.

``output_hz`` and ``reference_hz`` are signed: below 0 Hz in reverse (the output by the response's run direction,
STATUS REV / INVCMD_STAT REVERSE; the reference by the run command the master sends, the last one while none is
sent), so that a reverse run plots below the axis; ``direction`` says the same in words.

Touches: nothing; reads the views, the metrics and the snapshots it is given.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ...cards.base import LED_WINDOW_NS
from ...config import Config
from ...drive.activity import regulation_names
from ...drive.monitors import SEL_MON_TABLES, ref_to_hz
from ...master.machine import CONNECTED as _CONNECTED
from ...master.types import StationState
from ...wire import CmdAlm, CommAlm, InvCmdStat, Link, M2Alarm, M2Status
from ...scenario.values import drive_settings

__all__ = ["FIGURE_FIELDS", "StationFigures", "NetworkFigures", "RttPercentiles", "run_direction", "station_key",
           "snapshot_figures", "REGULATION_WINDOW_NS", "REGULATION_OF"]

#: The keys of one station's figures, in order (docs/control.md, "Station figures").
FIGURE_FIELDS = ("address", "name", "card", "link", "phase", "connected", "alarm", "warnings", "leds", "led_colors",
                 "running", "direction", "reference_hz", "output_hz", "output_current_a", "dc_bus_v",
                 "motor_speed_rpm", "regulation", "rtt_us", "rtt_p50_us", "rtt_p99_us", "missed", "late")
#: A slave's snapshot names the regulation states its drive was in during this long before it (the period the
#: trace asks the slaves of ``mlink-sim up`` for their snapshots at: aio/present/trace.py SNAPSHOT_EVERY_S).
REGULATION_WINDOW_NS = 500_000_000
#: A regulation code (:meth:`mlink_sim.drive.Drive.regulation`) -> the names of its states, one tuple per code (made
#: once: the figures of every sample take one of these).
REGULATION_OF: tuple[tuple[str, ...], ...] = tuple(regulation_names(code) for code in range(8))

# Plain ints (and machine.CONNECTED, a tuple of members): the figures are read many times a second, and an enum's
# ``&`` and hash run in Python.
_COMM_ALARMS = frozenset({int(M2Alarm.WDT_ERROR), int(M2Alarm.COMM_ERROR)})  #: SI-T3 Table 20 "LED (ERR) ON"
_FORWARD, _REVERSE = int(InvCmdStat.FORWARD), int(InvCmdStat.REVERSE)
_SEL_MON1, _SEL_MON2 = int(InvCmdStat.SEL_MON1), int(InvCmdStat.SEL_MON2)
_RUNX, _REV = int(M2Status.RUNX), int(M2Status.REV)
#: What a SEL_MON selection carries, by monitor name (drive/monitors.py): the figure it fills.
_MONITOR_FIGURE = {"U1-01": "reference_hz", "U-01": "reference_hz", "U1-05": "motor_speed_rpm",
                   "U1-07": "dc_bus_v", "U-05": "dc_bus_v"}
#: The slave snapshot's drive figures, by figure (cards/snapshot.py ``DriveSnapshot``).
_SNAPSHOT_FIGURE = {"reference_hz": "reference_hz", "dc_bus_v": "dc_bus_v", "motor_speed_rpm": "motor_rpm"}


def station_key(address: int) -> str:
    """``0x21``: how the control endpoint and the report name a station."""
    return f"0x{address:02x}"


def run_direction(link: Link, status: int) -> str | None:
    """``"forward"``, ``"reverse"`` or None (stopped) from a response's status: ML-III INVCMD_STAT FORWARD/REVERSE
    (SI-ET3 "INVCMD_STAT"), ML-I/II STATUS RUNX with REV (SI-T3 / SI-T/V7 "STATUS Field")."""
    if link is Link.ML3:
        return "forward" if status & _FORWARD else "reverse" if status & _REVERSE else None
    if not status & _RUNX:
        return None
    return "reverse" if status & _REV else "forward"


def _signed(raw: int) -> int:
    return raw - 0x10000 if raw >= 0x8000 else raw


def _code_name(table: Any, code: int) -> str:
    try:
        return str(table(code).name)
    except ValueError:
        return f"{code:X}H"


class RttPercentiles:
    """Each station's RTT p50 and p99 in µs, *per_call* stations refreshed at each :meth:`step`, in turn.

    One station's percentiles scan its histogram's non-zero buckets (about a millisecond for a few thousand of
    them): refreshing all 62 stations at every status (10 Hz) would cost the master's loop tens of cycles, so
    the figures are as fresh as the last refresh of that station (62 stations, 10 Hz, 4 a call: 1.6 s)."""

    def __init__(self, per_call: int = 4) -> None:
        self.per_call = per_call
        self._values: dict[int, tuple[float | None, float | None]] = {}
        self._next = 0

    def step(self, metrics: Any) -> None:
        stations = metrics.stations
        order = sorted(stations)
        for _ in range(min(self.per_call, len(order))):
            address = order[self._next % len(order)]
            self._next += 1
            hist = stations[address].rtt
            p50, p99 = hist.percentiles((50.0, 99.0))
            self._values[address] = (round(p50 / 1000, 1), round(p99 / 1000, 1)) if p99 else (None, None)

    def get(self, address: int) -> tuple[float | None, float | None]:
        return self._values.get(address, (None, None))


class StationFigures:
    """One station's figures: the constants worked out once (names, the drive's frequency units and poles, what
    each SEL_MON code carries on its card), :meth:`of` the figures of one view."""

    __slots__ = ("address", "key", "name", "card", "link", "settings", "_poles", "_monitors",
                 "_ml3", "_colors", "_reverse")

    def __init__(self, st: Any) -> None:
        assert st.link is not None  # the config's validation fills it in
        self.address: int = st.address
        self.key = station_key(st.address)
        self.name = f"{st.address:02X}H"
        self.card: str = st.card
        self.link: Link = st.link
        self.settings = drive_settings(st)  #: the drive's settings as the config's parameters make them
        self._poles = self.settings.pole_pairs
        table = SEL_MON_TABLES.get(st.profile.selections, ("",) * 16)
        self._monitors = tuple(_MONITOR_FIGURE.get(name) for name in table)  #: SEL_MON code -> figure or None
        self._ml3 = st.link is Link.ML3  # the SI-ET3's link, and only its
        self._colors = ({"R/E": "green", "CON": "green", "LK1": "green", "LK2": "green"} if self._ml3 else
                        {"RUN": "green", "ERR": "red", "TX": "green", "RX": "green"})
        self._reverse = False  # the last run command the master sent was reverse: the reference's sign

    def _hz(self, raw: int) -> float:
        raw = _signed(raw)
        hz = ref_to_hz(self.settings, abs(raw))
        return round(-hz if raw < 0 else hz, 2)

    def of(self, view: Any, sel_mon: int = 0x41, now_ns: int | None = None,
           rtt: tuple[float | None, float | None] = (None, None),
           snapshot: Mapping[str, Any] | None = None, run: tuple[bool, bool] = (False, False)) -> dict[str, Any]:
        """The figures of *view* (the master's :class:`~mlink_sim.master.StationView`), its monitors read as
        *sel_mon* selects them, TX/RX/LK1 judged at *now_ns* (the master's clock; None: lit while answering),
        *rtt* from :class:`RttPercentiles`, the slave's *snapshot* (its stats entry) where there is one, and *run*
        the run command the master sends (forward, reverse: the reference's sign)."""
        if run[0] != run[1]:
            self._reverse = run[1]
        status = view.status
        direction = run_direction(self.link, status)
        alarm, warnings = self._alarms(view)
        monitors: dict[str, float | None] = {"reference_hz": None, "motor_speed_rpm": None, "dc_bus_v": None}
        answering = view.state is not StationState.OFFLINE and view.responses > 0
        if answering:
            for code, raw, enabled in ((sel_mon & 0xF, view.mon1, _SEL_MON1),
                                       (sel_mon >> 4 & 0xF, view.mon2, _SEL_MON2)):
                figure = self._monitors[code]
                if figure is None or (self._ml3 and not status & enabled):
                    continue
                if figure == "dc_bus_v":
                    monitors[figure] = float(_signed(raw))
                elif figure == "motor_speed_rpm":
                    monitors[figure] = round(self._hz(raw) * 60.0 / self._poles, 1)
                else:
                    monitors[figure] = self._hz(raw)
        ref = monitors["reference_hz"]
        drive = snapshot.get("drive") if snapshot else None
        if isinstance(drive, Mapping):
            for figure, key in _SNAPSHOT_FIGURE.items():
                if monitors[figure] is None and isinstance(drive.get(key), (int, float)):
                    monitors[figure] = round(float(drive[key]), 2)
            ref = monitors["reference_hz"]
            extra = snapshot.get("warnings") if snapshot and view.warning else None  # what the warning is
            if isinstance(extra, list):
                warnings += [w for w in extra if isinstance(w, str) and w not in warnings]
        leds, colors = self._leds(view, now_ns, alarm is not None, snapshot)
        p50, p99 = rtt
        out = view.output_hz if answering else None
        if out is not None and direction == "reverse":
            out = -out
        if ref is not None and self._reverse:
            ref = -abs(ref)
        reg = snapshot.get("regulation") if snapshot else None
        rtt_ns = view.rtt_ns
        return {
            "address": self.key, "name": self.name, "card": self.card, "link": self.link.name,
            "phase": view.phase, "connected": view.state in _CONNECTED, "alarm": alarm, "warnings": warnings,
            "leds": leds, "led_colors": colors, "running": direction is not None, "direction": direction,
            "reference_hz": ref, "output_hz": out,
            "output_current_a": round(view.output_current * 0.1, 1) if answering else None,
            "dc_bus_v": monitors["dc_bus_v"], "motor_speed_rpm": monitors["motor_speed_rpm"],
            "regulation": REGULATION_OF[reg & 7] if isinstance(reg, int) else None,
            "rtt_us": round(rtt_ns / 1000, 1) if answering and rtt_ns is not None else None, "rtt_p50_us": p50, "rtt_p99_us": p99, "missed": view.missing, "late": view.late,
        }

    def _alarms(self, view: Any) -> tuple[dict[str, Any] | None, list[str]]:
        """The alarm (``{"code": "E6H", "name": "COMM_ERROR"}``) and the warnings' names. ML-I/II: the ALARM byte
        (SI-T3 Tables 23/25/26), a warning while STATUS.WARNG is set without STATUS.ALM; ML-III: COMM_ALM 8H–CH and
        CMD_ALM 8H–CH are alarms, 1H–3H warnings (SI-ET3 "COMM_ALM", "CMD_ALM"); a drive fault (CMD_STAT.D_ALM) has
        the code the master read with ALM_RD (SI-ET3 Tables 16/17), ``{"code": null, "name": "D_ALM"}`` until then."""
        warnings: list[str] = []
        alarm: dict[str, Any] | None = None
        if not self._ml3:
            code = view.alarm
            if not code:
                return ({"code": None, "name": "ALM"} if view.fault else None), (["WARNG"] if view.warning else [])
            name = view.alarm_name or f"{code:02X}H"
            if view.warning and not view.fault and 0x90 <= code < 0xE0:
                return None, [name]
            return {"code": f"{code:02X}H", "name": name}, warnings
        for label, table, code in (("COMM_ALM", CommAlm, view.comm_alm), ("CMD_ALM", CmdAlm, view.cmd_alm)):
            if not code:
                continue
            if code >= 8 and alarm is None:
                alarm = {"code": f"{label} {code:X}H", "name": _code_name(table, code)}
            elif code < 8:
                warnings.append(_code_name(table, code))
        if alarm is None and view.fault:  # the drive's fault code as the master read it (ALM_RD), once it has
            alarm = ({"code": f"{view.alarm:02X}H", "name": view.alarm_name or f"{view.alarm:02X}H"} if view.alarm
                     else {"code": None, "name": "D_ALM"})
        if view.warning:
            warnings.append("D_WAR")
        return alarm, warnings

    def _leds(self, view: Any, now_ns: int | None, alarm: bool,
              snapshot: Mapping[str, Any] | None) -> tuple[dict[str, str], dict[str, str]]:
        answering = view.state is not StationState.OFFLINE and view.responses > 0
        if not answering and snapshot and isinstance(snapshot.get("leds"), Mapping):
            return dict(snapshot["leds"]), dict(snapshot.get("led_colors") or self._colors)
        last = view.last_response_ns
        flowing = answering and (now_ns is None or (last is not None and now_ns - last <= LED_WINDOW_NS))
        lit = "on" if flowing else "off"
        if self._ml3:  # SI-ET3 Table 4
            error = alarm or bool(view.cmd_alm)
            return ({"R/E": "on" if answering else "off", "CON": "on" if view.state in _CONNECTED else "off",
                     "LK1": lit, "LK2": "off"}, {**self._colors, "R/E": "red" if error else "green"})
        comm = view.state is StationState.ALARM or view.alarm in _COMM_ALARMS  # SI-T3 Table 3, SI-T/V7 §3.3
        return ({"RUN": "on" if answering else "off", "ERR": "on" if comm else "off", "TX": lit,
                 "RX": "on" if view.sent else "off"}, self._colors)


class NetworkFigures:
    """The figures of every station of a network (:class:`StationFigures` each, built once from *config*)."""

    def __init__(self, config: Config, rtt_per_call: int = 4) -> None:
        self.by_address = {st.address: StationFigures(st) for st in config.station}
        self.rtt = RttPercentiles(rtt_per_call)

    def station(self, address: int, net: Any,
                snapshots: Mapping[int, Mapping[str, Any]] | None = None) -> dict[str, Any]:
        """The figures of station *address* of *net* (a ``NetworkApi``), with its RTT figures as last refreshed
        (:meth:`stations`) and the slave's snapshot in *snapshots* (address -> stats entry) if there."""
        master = net.master(address)
        control = master.core.control(address)
        return self.by_address[address].of(
            master.view(address), control.sel_mon, master.now_ns(), self.rtt.get(address),
            None if snapshots is None else snapshots.get(address), (control.forward, control.reverse))

    def stations(self, net: Any, metrics: Any = None,
                 snapshots: Mapping[int, Mapping[str, Any]] | None = None) -> list[dict[str, Any]]:
        """Every station's figures, in the config's order; refreshes a few stations' RTT figures from *metrics*."""
        if metrics is not None:
            self.rtt.step(metrics)
        return [self.station(a, net, snapshots) for a in self.by_address]


def _rounded(value: Any, digits: int) -> float | None:
    return round(float(value), digits) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def snapshot_figures(snap: Mapping[str, Any]) -> dict[str, Any]:
    """The figures of a standalone slave's station from its snapshot alone (its stats entry: the card's view, not
    a master's), keyed as :data:`FIGURE_FIELDS`: the drive's own figures (the frequencies signed by the drive's
    direction, DriveSnapshot.reverse; the regulation from the snapshot's ``"regulation"`` code), the LEDs the card
    lights; no RTT, no missed or late answers (null: only a master counts them). The alarm: ML-II ALARM E0H and above, ML-III COMM_ALM
    or CMD_ALM 8H and above (SI-T3 Table 23, SI-ET3 "COMM_ALM" / "CMD_ALM"), else the drive's fault."""
    address = int(snap.get("address", 0))
    link = str(snap.get("link", ""))
    code, cmd_alm = int(snap.get("alarm_code") or 0), int(snap.get("cmd_alm") or 0)
    name = snap.get("alarm_name")
    drive = snap.get("drive") if isinstance(snap.get("drive"), Mapping) else {}
    assert isinstance(drive, Mapping)
    warnings = [w for w in snap.get("warnings") or () if isinstance(w, str)]
    alarm: dict[str, Any] | None = None
    if link == "ML3":
        for label, table, value in (("COMM_ALM", CommAlm, code), ("CMD_ALM", CmdAlm, cmd_alm)):
            if value >= 8 and alarm is None:
                alarm = {"code": f"{label} {value:X}H", "name": _code_name(table, value)}
    elif code >= 0xE0:
        alarm = {"code": f"{code:02X}H", "name": name or f"{code:02X}H"}
    elif code and (name or f"{code:02X}H") not in warnings:
        warnings.append(name or f"{code:02X}H")
    if alarm is None and isinstance(drive.get("fault"), str):
        alarm = {"code": None, "name": drive["fault"]}
    running = bool(drive.get("running"))
    sign = -1.0 if drive.get("reverse") else 1.0
    phase = int(snap.get("phase") or 0)
    reg = snap.get("regulation")
    ref, out = _rounded(drive.get("reference_hz"), 2), _rounded(drive.get("output_hz"), 2)
    leds = snap.get("leds")
    colors = snap.get("led_colors")
    return {
        "address": station_key(address), "name": f"{address:02X}H", "card": snap.get("card"), "link": link,
        "phase": phase, "connected": snap.get("connected_source") is not None, "alarm": alarm, "warnings": warnings,
        "leds": dict(leds) if isinstance(leds, Mapping) else {},
        "led_colors": dict(colors) if isinstance(colors, Mapping) else {},
        "running": running, "direction": ("reverse" if drive.get("reverse") else "forward") if running else None,
        "reference_hz": None if ref is None else sign * ref, "output_hz": None if out is None else sign * out,
        "output_current_a": _rounded(drive.get("output_current_a"), 1), "dc_bus_v": _rounded(drive.get("dc_bus_v"), 1),
        "motor_speed_rpm": _rounded(drive.get("motor_rpm"), 1),
        "regulation": REGULATION_OF[reg & 7] if isinstance(reg, int) else None, "rtt_us": None, "rtt_p50_us": None,
        "rtt_p99_us": None,
        "missed": None, "late": None,
    }
