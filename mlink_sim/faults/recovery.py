"""Recovery as a measured figure: each fault injected into a station is an :class:`Episode`; once it
has ended, the station's recovery time is the time from its end to the first cycle at which the master sees the
station back at its target phase (3, or 2 without ``sync``) with no alarm (docs/faults.md, "Recovery").

Sans-I/O: times come in as ``now`` (ns); whether a station is healthy is a predicate the caller supplies (the master's
view of it). :meth:`RecoveryLog.poll` costs nothing while no episode waits for its recovery.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["Episode", "RecoveryLog", "WATCH_NS", "SETTLE_POLLS"]

#: An episode not recovered this long after its end is given up (counted as not recovered).
WATCH_NS = 60_000_000_000
#: Recovered means healthy at this many polls (cycles) in a row; the recovery time runs to the first of them. A
#: station can look healthy for a moment at a fault's end before its effect shows (a frozen WDT count jumping
#: back, an answer in flight), so one healthy view is not enough.
SETTLE_POLLS = 3


@dataclass
class Episode:
    """One fault of one station: when it began and ended and when the station was healthy again (ns)."""

    station: int
    what: str  #: the fault's description, e.g. "silence for=200ms"
    start_ns: int
    end_ns: int | None = None  #: None: still going (or ends when the caller says so)
    recovered_ns: int | None = None
    gave_up: bool = False
    notes: list[str] = field(default_factory=list)
    healthy_since: int | None = None  #: start of the current run of healthy polls
    healthy_polls: int = 0
    name: str = ""  #: the fault's name (docs/faults.md, "Names"), once the control plane gave it one
    #: what the fault did to the station's datagrams while it was in force (the report's ``injected`` keys)
    injected: dict[str, int] = field(default_factory=dict)

    @property
    def recovery_ns(self) -> int | None:
        """Time from the end of the fault to the station's recovery, or None (not ended or not recovered)."""
        if self.end_ns is None or self.recovered_ns is None:
            return None
        return self.recovered_ns - self.end_ns

    def as_dict(self) -> dict[str, object]:
        """The episode as JSON (a control reply, the plugin's host)."""
        return {"station": self.station, "what": self.what, "start_ns": self.start_ns, "end_ns": self.end_ns,
                "recovered_ns": self.recovered_ns, "recovery_ns": self.recovery_ns, "notes": list(self.notes),
                "name": self.name, "injected": dict(self.injected)}


class RecoveryLog:
    """Episodes of every station; *on_recovery(station, ns)* is called once per recovered episode."""

    def __init__(self, on_recovery: Callable[[int, int], None] | None = None,
                 on_gave_up: Callable[[int], None] | None = None) -> None:
        self.episodes: list[Episode] = []
        self._open: list[Episode] = []  # not settled yet
        self._on_recovery = on_recovery
        self._on_gave_up = on_gave_up

    @property
    def watching(self) -> bool:
        return bool(self._open)

    def begin(self, station: int, what: str, now: int, end_ns: int | None = None) -> Episode:
        """A fault of *station* begins at *now*; it ends at *end_ns* if known (else call :meth:`end`)."""
        ep = Episode(station, what, now, end_ns)
        self.episodes.append(ep)
        self._open.append(ep)
        return ep

    def end(self, episode: Episode, now: int) -> None:
        if episode.end_ns is None or episode.end_ns > now:
            episode.end_ns = now

    def poll(self, now: int, healthy: Callable[[int, int], bool]) -> None:
        """Check every ended, unsettled episode at *now*: recovered when *healthy(station, end_ns)* – healthy on
        the evidence of an answer received after the fault's end (a view not yet updated proves nothing)."""
        if not self._open:
            return
        still: list[Episode] = []
        for ep in self._open:
            end = ep.end_ns
            if end is None or now < end:
                still.append(ep)
            elif healthy(ep.station, end):
                if ep.healthy_since is None:
                    ep.healthy_since = now
                ep.healthy_polls += 1
                if ep.healthy_polls < SETTLE_POLLS:
                    still.append(ep)
                    continue
                ep.recovered_ns = ep.healthy_since
                if self._on_recovery is not None:
                    self._on_recovery(ep.station, ep.healthy_since - end)
            elif now - end > WATCH_NS:
                ep.gave_up = True
                if self._on_gave_up is not None:
                    self._on_gave_up(ep.station)
            else:
                ep.healthy_since, ep.healthy_polls = None, 0
                still.append(ep)
        self._open = still

    def latest(self, station: int, before_ns: int | None = None) -> Episode | None:
        """The last episode of *station* begun at or before *before_ns* (any time when None)."""
        for ep in reversed(self.episodes):
            if ep.station == station and (before_ns is None or ep.start_ns <= before_ns):
                return ep
        return None
