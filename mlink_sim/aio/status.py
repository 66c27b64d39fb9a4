"""The compact live status of ``mlink-sim up``: one line per station (phase, run state, frequency, alarms)."""

from __future__ import annotations

from typing import Any

from ..config import Config
from ..wire import InvCmdStat, Link, M2Status

__all__ = ["render_status", "station_line"]


def station_line(st: Any, view: Any, hz: float) -> str:
    """``21H si-t3   P3  FWD  30.00 Hz  ok         rtt 0.21 ms``"""
    link: Link = st.link
    status = view.status
    if link is Link.ML3:
        fwd, rev = status & InvCmdStat.FORWARD, status & InvCmdStat.REVERSE
    else:
        run = status & M2Status.RUNX
        rev = run and status & M2Status.REV
        fwd = run and not rev
    run_state = "FWD" if fwd else "REV" if rev else "stop"
    if view.fault or view.alarm or view.comm_alm or view.cmd_alm:
        alarm = view.alarm_name or (f"COMM_ALM {view.comm_alm:X}H" if view.comm_alm else "alarm")
    elif view.warning:
        alarm = f"warn {view.alarm_name or ''}".strip()
    else:
        alarm = "ok"
    rtt = f"rtt {view.rtt_ns / 1e6:.2f} ms" if view.rtt_ns is not None else "rtt  -"
    phase = f"P{view.phase}" if view.phase else view.state.value
    return (f"  {st.address:02X}H {st.card:<8} {link.name} {phase:<8} {run_state:<4} {hz:7.2f} Hz  "
            f"{alarm:<14} {rtt}")


def render_status(config: Config, net: Any, t: float, scales: dict[int, Any]) -> str:
    """All stations, under a header with the elapsed time; *scales* convert output frequency words to Hz."""
    lines = [f"[{t:6.1f}s] {config.network.name}"]
    for st in config.station:
        view = net.view(st.address)
        try:
            hz = scales[st.address].to_hz(view.output_freq)
        except Exception:  # noqa: BLE001 - a display must never stop the run
            hz = float("nan")
        lines.append(station_line(st, view, hz))
    return "\n".join(lines)
