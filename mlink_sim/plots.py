"""The plotting vocabulary of the HTML report (``mlink_sim.metrics.html``) and the live page (``mlink_sim.web``): one
definition of what a station's plots show, in which colours, how an action, a check and a fault are marked and what
a shaded band means, so that a run reads the same on the page while it runs and in the report afterwards
(docs/report.md, docs/web.md).

Data only, JSON-able (:func:`vocabulary`: the page reads it from the web server as ``/plots.json``). A leaf of the
package: the report and the web server both read it and neither may import the other.
"""

from __future__ import annotations

from typing import Any

__all__ = ["STATION_PLOTS", "MARKS", "BANDS", "REGULATION_BANDS", "BRIDGE_S", "TIME_LABEL", "BEFORE_ZERO",
           "mark_kind", "vocabulary"]

#: A station's plots, in order: what each shows, its unit and its series (a station figure of
#: docs/control.md, "Station figures"; its label and colour; ``dash``: drawn dashed).
STATION_PLOTS: tuple[dict[str, Any], ...] = (
    {"id": "hz", "title": "frequency", "unit": "Hz",
     "series": ({"key": "reference_hz", "label": "reference Hz", "color": "#8c959f", "dash": True},
                {"key": "output_hz", "label": "output Hz", "color": "#1f6feb"})},
    {"id": "current", "title": "output current", "unit": "A",
     "series": ({"key": "output_current_a", "label": "current A", "color": "#d97706"},)},
    {"id": "bus", "title": "DC bus", "unit": "V",
     "series": ({"key": "dc_bus_v", "label": "DC bus V", "color": "#7c3aed"},)},
)
#: How a moment is marked on a station's plots: a numbered circle on a vertical line, in the colour of its kind; the
#: numbers are listed under the plots with what happened (a legend that prints).
MARKS: dict[str, dict[str, str]] = {
    "action": {"color": "#57606a", "label": "an action: a timeline step, a request that acts"},
    "check-ok": {"color": "#1a7f37", "label": "a check that held"},
    "check-fail": {"color": "#cf222e", "label": "a check that failed"},
    "fault": {"color": "#bc4c00", "label": "a fault or an impairment began or ended"},
    "recovered": {"color": "#2da44e", "label": "the station recovered after a fault"},
    "alarm": {"color": "#a40e26", "label": "an alarm (the live page)"},
}
#: What a shaded band means: the drive's own regulation (mlink_sim.drive.activity.REGULATION, by its names) and a
#: fault or impairment in force; its colour (drawn translucent) and its legend.
BANDS: dict[str, dict[str, str]] = {
    "stall-accel": {"color": "#f2cc60", "label": "current limit (stall prevention, accel: L3-01/L3-02, n093)"},
    "stall-decel": {"color": "#a5d6ff", "label": "DC bus regulation (stall prevention, decel: L3-04, n092)"},
    "torque-limit": {"color": "#d8b9ff", "label": "torque limit"},
    "fault": {"color": "#f4c7c3", "label": "a fault or an impairment in force"},
}
#: The bands of the drive's regulation, in order.
REGULATION_BANDS = ("stall-accel", "stall-decel", "torque-limit")
#: A regulation state off for less than this between two samples that have it is one band: stall prevention goes
#: on and off every few milliseconds around its level, and holds the ramp all along.
BRIDGE_S = 0.25
#: The time axis of every plot: seconds from the timeline's 0 s (the end of bring-up).
TIME_LABEL = "t (s)"
#: What a time before the timeline's 0 s is: bring-up (the stations were being brought up; docs/control.md).
BEFORE_ZERO = "bring-up"


def mark_kind(event: str, detail: str = "") -> str | None:
    """The :data:`MARKS` kind of a trace's action row (*event*, *detail*: docs/report.md, "Traces"), or None for one
    that is not marked (a fault's end is a band's edge, an unrecovered station a row of the faults table)."""
    if event == "check":
        return "check-ok" if detail.startswith("ok") else "check-fail"
    if event in ("step", "control"):
        return "action"
    if event in ("fault", "impair-start"):
        return "fault"
    if event == "recovered":
        return "recovered"
    return None


def vocabulary() -> dict[str, Any]:
    """The vocabulary as one JSON-able object (what the live page reads)."""
    return {"station_plots": [{**p, "series": list(p["series"])} for p in STATION_PLOTS], "marks": MARKS,
            "bands": BANDS, "regulation_bands": list(REGULATION_BANDS), "bridge_s": BRIDGE_S,
            "time_label": TIME_LABEL, "before_zero": BEFORE_ZERO}
