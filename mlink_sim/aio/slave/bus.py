"""A slave worker's per-read path: the datagrams of one socket to the stations they name, and their answers back.

:class:`~mlink_sim.aio.slave.server.SlaveServer` moves the bytes (its sockets, its 1 ms tick, EEPROM writes); every
datagram it reads goes through here on its way to a card core, and every answer on its way back. On a shared
port (the stations of one link in one worker, ``SlaveServer(shared=True)``) that is 62 datagrams per read at
the largest ML-III line, so the module is compiled with the cores (``mlink_sim._accel.COMPILED_MODULES``; its
classes are native: no attributes beyond those declared). It holds no protocol logic: which station a datagram
is for is the envelope's station byte (byte 3, docs/wire-format.md), and what it means is the card's business.

* :class:`Port`: one station as its socket sees it. :meth:`Port.serve` hands a read's datagrams to the card
  (``Station.receive``) and collects the answers. More than *keep* datagrams from one source in one read means
  the worker fell that many cycles behind: the oldest are counted as ``SUPERSEDED`` drops and only the newest
  *keep* are answered (``SlaveServer._keep_behind`` says why, and how "absorb" sizes it). Once the answers are
  sent, :meth:`Port.after_send` has the card finish what its commands left for after their answers
  (``Station.finish``: log lines, settings built ahead; docs/timing.md, "When each command is answered") and hands
  an EEPROM image it made to the server: nothing of that is between a command and its answer.
* :class:`Bus`: the stations of one shared socket. :meth:`Bus.serve` groups a read by station byte (each
  station's datagrams in arrival order, the stations in the order they first appear) and serves each group
  through that station's :class:`Port`. A read with one datagram per station (every cycle's, unless the worker
  fell behind) is the same grouping; it is served in one pass, without building the groups. A datagram for no
  station hosted there (or shorter than 4 bytes) is counted in :attr:`Bus.unaddressed`, as a station on a bus
  ignores frames for others. A read with a backlog (the worker held up, or the master catching up on cycles) is
  answered ahead too, as far as each card's prediction carries it (below).
* **Answers made ahead** (docs/cards.md, "The answer made ahead"). After each read a card may offer the answer to
  the command it expects next (``Station.prediction``, :mod:`mlink_sim.cards.prediction`), kept on its
  :class:`Port`. :meth:`Bus.serve` answers a datagram its prediction names straight away (one C call, no card
  code), so that the cards' time is no longer between the master's commands and their answers; once the read's
  answers are sent, :meth:`Bus.settle` hands those datagrams to their cards (``receive``, at the read's time), counts
  any answer of theirs that differs from the one sent in :attr:`Port.mispredicted` (and in the card's
  ``internal_errors``: it would be a bug, and it is logged), has every card that took a command of the read finish
  what it left (:meth:`Port.after_send`), and takes every served card's next prediction. In a read with several commands for a station, the prediction is moved on from one to the next
  (``Prediction.advance``), so a backlog is answered ahead as a cycle is; where it stops holding (or a station has
  none), the card takes the commands answered so far, then the next one in the chain, and the prediction it offers
  right after answers the rest ahead again (:meth:`Bus._serve_backlog`). Whatever else reaches a card between
  two reads (its ``poll``, a control request, an EEPROM write) drops its prediction first (:meth:`Port.forget`).
* **A backlog's answers** go out newest cycle first (:func:`_newest_first`): in a read with several commands for a
  station, all answered ahead, those answers are ranked by how many of its commands in the read come after them, and
  sent rank by rank, every other answer in the first. The older commands' answers are due at the master already (their
  cycle began a transmission cycle before the newer one's); the newest can still be on time. The cards take every
  command in its order all the same (:meth:`Bus.settle`) (docs/cards.md, "A backlog's answers").
* :func:`due`: which stations' ``poll`` is due at a tick (``Station.next_deadline``): a scan of every hosted
  station once per millisecond.

Touches: nothing of the operating system: the card cores and the answers it hands back (compiled with the cores).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..._log import get_logger
from ...cards.base import Station
from ...cards.prediction import Prediction

__all__ = ["Bus", "Port", "due"]

Batch = list[tuple[bytes, Any]]

_log = get_logger("mlink_sim.aio.slave.bus")


class Port:
    """One hosted station's share of a read (see the module docstring). *hosted*: the
    :class:`~mlink_sim.aio.slave.server.HostedStation` it serves (its ``responses`` read :attr:`responses`);
    *on_eeprom(hosted)*: called after a read that left the card with an EEPROM image to write; *clock()*: the time
    each datagram is handed to the card at (ns; the worker's ``time.monotonic_ns``)."""

    def __init__(self, station: Station, hosted: Any, keep: int, on_eeprom: Callable[[Any], None],
                 clock: Callable[[], int]) -> None:
        self.station: Station = station
        self.clock: Callable[[], int] = clock
        self.hosted: Any = hosted
        self.keep: int = keep
        self.on_eeprom: Callable[[Any], None] = on_eeprom
        self.receive: Callable[[bytes, Any, int], bytes | None] = station.receive
        self.pred: Prediction | None = None  #: the card's answer to the command it expects next (Bus.serve)
        self.responses: int = 0  #: the answers sent (a native count: the per-cycle path touches no Python object)
        if hosted is not None:  # the station's count goes on from a port it had before (HostedStation.bus_port)
            before = hosted.bus_port
            if before is not None:
                self.responses = before.responses
            hosted.bus_port = self
        self.mispredicted: int = 0  #: answers sent ahead that the card's own answer then differed from

    def serve(self, batch: Batch, out: Batch) -> None:
        """Answer *batch* (this station's datagrams of one read, oldest first), appending ``(answer, source)`` to
        *out* (a shared socket's list holds the other stations' answers too)."""
        self.pred = None
        if len(batch) > self.keep:
            batch = _newest(batch, self.station.counters, self.keep)
        receive, clock = self.receive, self.clock
        n = 0
        for data, addr in batch:
            response = receive(data, addr, clock())
            if response is not None:
                out.append((response, addr))
                n += 1
        if n:
            self.responses += n

    def serve_one(self, data: bytes, addr: Any, now: int, out: Batch) -> None:
        """One datagram for this station, taken by its card at *now*: a read with one for it, or a backlog's
        command in the chain (:meth:`Bus._serve_backlog`, at the read's time)."""
        self.pred = None
        response = self.station.receive(data, addr, now)
        if response is not None:
            out.append((response, addr))
            self.responses += 1

    def after_send(self) -> None:
        """Once the answers of a read are sent: the card finishes what its commands left for after their answers
        (``Station.finish``), and an EEPROM image it made goes to the server (*on_eeprom*)."""
        station = self.station
        station.finish()
        if station.eeprom_pending:
            self.on_eeprom(self.hosted)

    def serve_untrusted(self, data: bytes, addr: Any, now: int, out: Batch) -> None:
        """A datagram from a source the allow list does not name (:mod:`mlink_sim.aio.slave.allow`): the card's
        ``receive_untrusted`` (a status query answered read-only, anything else counted and dropped)."""
        self.pred = None
        response = self.station.receive_untrusted(data, addr, now)
        if response is not None:
            out.append((response, addr))
            self.responses += 1

    def settle(self, data: bytes, addr: Any, answer: bytes, now: int) -> None:
        """The card takes *data*, which *answer* was sent to ahead (:meth:`Bus.settle`)."""
        station = self.station
        response = station.receive(data, addr, now)
        self.responses += 1
        if response != answer:  # a bug: counted as the card's internal error too (the report's counters)
            self.mispredicted += 1
            station.record_internal_error()
            if self.mispredicted == 1:
                _log.error("answer_mispredicted", station=f"{station.address:02X}H", sent=answer.hex(),
                           card=None if response is None else response.hex())

    def forget(self) -> None:
        """Drop the card's prediction: something other than a read reached the card."""
        self.pred = None


class Bus:
    """The stations of one shared socket, by station address (see the module docstring). *clock()*: the time a
    read is stamped with, for the predictions (ns; the worker's ``time.monotonic_ns``)."""

    def __init__(self, ports: list[Port], clock: Callable[[], int] | None = None) -> None:
        self.ports: dict[int, Port] = {int(p.station.address): p for p in ports}
        self.unaddressed: int = 0  #: datagrams for no station hosted here (or shorter than 4 bytes)
        self.clock: Callable[[], int] = clock if clock is not None else (ports[0].clock if ports else _zero)
        self.ahead: int = 0  #: answers sent ahead, from the cards' predictions
        self._now: int = 0  # the last read's stamp
        self._sent_ahead: list[tuple[Port, bytes, Any, bytes]] = []  # the last read's, until settle()
        self._served: list[Port] = []  # the ports whose card took (or, after settle, takes) a command of the last read
        self._untrusted: list[Port] = []  # the ports whose card took a datagram of another source in the last read

    def serve(self, batch: Batch) -> Batch:
        """The answers to one read of the shared socket, in the order the stations first appear in it (a backlog's
        newest cycle first: the module docstring); then :meth:`settle`, once they are sent."""
        keys = [item[0][3] if len(item[0]) > 3 else -1 for item in batch]
        ports = self.ports
        if len(set(keys)) == len(keys):  # one datagram per station: the groups are the datagrams, in order
            now = self._now = self.clock()
            out: Batch = []
            sent_ahead, served = self._sent_ahead, self._served
            for key, item in zip(keys, batch):
                port = ports.get(key)
                if port is None:
                    self.unaddressed += 1
                    continue
                pred = port.pred
                if pred is not None:
                    data, addr = item
                    answer = pred.answer_to(data, addr, now)
                    if answer is not None:
                        port.pred = None
                        out.append((answer, addr))
                        sent_ahead.append((port, data, addr, answer))
                        served.append(port)
                        continue
                port.serve_one(item[0], item[1], port.clock(), out)
                served.append(port)
            return out
        per: dict[int, Batch] = {}
        for item in batch:
            data = item[0]
            key = data[3] if len(data) > 3 else -1
            items = per.get(key)
            if items is None:
                per[key] = [item]
            else:
                items.append(item)
        now = self._now = self.clock()
        out = []
        served = self._served
        runs: list[tuple[int, int]] = []  # where out holds a station's backlog answered ahead in full
        for key, items in per.items():
            port = ports.get(key)
            if port is None:
                self.unaddressed += len(items)
                continue
            start = len(out)
            if len(items) > port.keep:  # beyond keep: the oldest superseded, the rest in the chain
                port.serve(items, out)
            elif self._serve_backlog(port, items, now, out) and len(items) > 1:
                runs.append((start, len(out)))
            served.append(port)
        if runs:
            return _newest_first(out, runs)
        return out

    def serve_untrusted(self, batch: Batch, out: Batch) -> None:
        """The datagrams of one read from sources the allow list does not name, each to the station its address
        byte names (:meth:`Port.serve_untrusted`); the answers appended to *out*."""
        now = self.clock()
        ports = self.ports
        for data, addr in batch:
            port = ports.get(data[3] if len(data) > 3 else -1)
            if port is None:
                self.unaddressed += 1
            else:
                port.serve_untrusted(data, addr, now, out)
                self._untrusted.append(port)

    def _serve_backlog(self, port: Port, items: Batch, now: int, out: Batch) -> bool:
        """A station's commands of one read (at most *keep*), in order: as many as its prediction answers ahead
        (:meth:`_run_ahead`); where it has none, or it stops holding, the card takes the next command in the chain
        (the ones answered ahead before it first), at the read's time, and the prediction it offers right after
        answers the rest ahead again. So a backlog after a poll dropped every prediction (a worker held up past
        the cards' silence deadline, the master's catch-up cycles coming after the poll: under the host-stall
        policy "absorb" only where a card's ``silence_tolerance_ns`` is shorter than the stall) costs the cards' own
        path the first commands of each station, not all of them (docs/cards.md, "A backlog"). True if every
        command was answered ahead."""
        i, n_items = 0, len(items)
        while True:
            n = self._run_ahead(port, items[i:] if i else items, now, out) if port.pred is not None else 0
            i += n
            if i >= n_items:
                return n == n_items
            if n:  # the card takes the commands answered ahead before the next one
                self._settle_last(n, now)
            data, addr = items[i]
            port.serve_one(data, addr, now, out)
            i += 1
            if i >= n_items:
                return False
            port.pred = port.station.prediction(now)  # right after the card's receive (Station.prediction)

    def _run_ahead(self, port: Port, items: Batch, now: int, out: Batch) -> int:
        """A backlog (several commands for one station in a read): as many of *items*, in order, as the card's
        prediction answers, each moved on to the next (:meth:`Prediction.advance
        <mlink_sim.cards.prediction.Prediction.advance>`); their answers appended to *out*, the commands kept for
        :meth:`settle`. Returns how many."""
        pred = port.pred
        port.pred = None
        assert pred is not None  # serve calls it only with one
        sent_ahead = self._sent_ahead
        n = 0
        for data, addr in items:
            answer = pred.answer_to(data, addr, now)
            if answer is None:
                break
            out.append((answer, addr))
            sent_ahead.append((port, data, addr, answer))
            n += 1
            if not pred.advance():
                break
        return n

    def _settle_last(self, n: int, now: int) -> None:
        """The card of the last *n* commands answered ahead takes them now, in order (:meth:`Port.settle`)."""
        sent_ahead = self._sent_ahead
        first = len(sent_ahead) - n
        for i in range(first, len(sent_ahead)):
            port, data, addr, answer = sent_ahead[i]
            port.settle(data, addr, answer, now)
        del sent_ahead[first:]
        self.ahead += n

    def settle(self) -> None:
        """After the last read's answers went out: the commands answered ahead go to their cards, at the read's
        time (:meth:`Port.settle`), every card that took a datagram in the read finishes what it left for after its
        answer (:meth:`Port.after_send`), and every card that took a command in the read offers its next
        prediction."""
        now = self._now
        sent_ahead = self._sent_ahead
        if sent_ahead:
            self.ahead += len(sent_ahead)
            for port, data, addr, answer in sent_ahead:
                port.settle(data, addr, answer, now)
            sent_ahead.clear()
        served = self._served
        if served:
            for port in served:
                port.after_send()
                port.pred = port.station.prediction(now)
            served.clear()
        untrusted = self._untrusted
        if untrusted:
            for port in untrusted:
                port.after_send()
            untrusted.clear()

    @property
    def mispredicted(self) -> int:
        """Answers sent ahead that their card's own answer then differed from (0, unless a card's prediction is
        wrong: each one is logged)."""
        return sum(p.mispredicted for p in self.ports.values())


def _zero() -> int:
    return 0


def _newest_first(out: Batch, runs: list[tuple[int, int]]) -> Batch:
    """*out* sent newest cycle first: the answers of each run (``out[start:end]``, one station's backlog answered
    ahead, oldest first) ranked by how many of the run come after them, every other answer ranked first; rank by
    rank, in the order of *out*. So every station's newest answer leads, and the oldest go last (the module
    docstring, "A backlog's answers")."""
    depth = max(end - start for start, end in runs)
    rank = [0] * len(out)
    for start, end in runs:
        for i in range(start, end - 1):
            rank[i] = end - 1 - i
    ranked: list[Batch] = [[] for _ in range(depth)]
    for r, item in zip(rank, out):
        ranked[r].append(item)
    return [item for group in ranked for item in group]


def _newest(batch: Batch, counters: Any, behind: int) -> Batch:
    """The newest *behind* datagrams of each source, in arrival order; the rest counted SUPERSEDED."""
    seen: dict[Any, int] = {}
    keep: Batch = []
    for item in reversed(batch):
        addr = item[1]
        n = seen.get(addr, 0)
        if n < behind:
            keep.append(item)
            seen[addr] = n + 1
        else:
            counters.drop("SUPERSEDED")
    keep.reverse()
    return keep


def due(stations: list[Station], now: int) -> list[int]:
    """The indices of the *stations* whose :meth:`~mlink_sim.cards.base.Station.poll` is due at *now*."""
    out: list[int] = []
    for i, st in enumerate(stations):
        deadline = st.next_deadline()
        if deadline is not None and deadline <= now:
            out.append(i)
    return out
