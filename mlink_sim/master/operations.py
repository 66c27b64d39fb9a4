"""The operator's side of the master core: requests built by what they do, DISCONNECT and CONNECT on request
(docs/master.md, "Requests").

As aioquic's connection builds its own frames, the core builds every command body an operator asks for: the
application names a parameter (``prm_rd(0x21, "C1-01")``) or an ID, the core resolves it against the station's
table (:mod:`.named`), builds the body of the station's generation (:class:`~.codec.Codec`), checks that it fits
its slot (:func:`.requests.build`) and queues it; the I/O layer only waits for the :class:`~.types.Request` to
complete. Its result is what the answer gives: a :class:`~.types.ParamValue`, the bytes read, the response body.
Time comes in as *now* (ns), the time the request is made, from which its *timeout_ns* runs (default: the plan's
``request_timeout_ns``; *now* None: the time of the core's latest call).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import Any

from . import named, requests
from .commands import Cmd
from .machine import MAY_HOLD_CONNECTION
from .plan import NetworkPlan
from .slave import Slave
from .types import Request, StationDisconnected, StationState

__all__ = ["Operations"]

S = StationState


class Operations:
    """The operator API of :class:`~.core.MasterCore` (its base): the stations of *plan* and their queues."""

    def __init__(self, plan: NetworkPlan) -> None:
        self.plan = plan
        self._now = 0  #: the time of the core's latest call (ns)
        self._stations: list[Slave] = []
        by_period: Counter[int] = Counter()
        for sp in plan.stations:
            period = sp.comm_cycles(plan.tcycle_ns)
            self._stations.append(Slave(sp, by_period[period], period, plan.spread, plan.tcycle_ns))
            by_period[period] += 1
        self._by_addr = {st.address: st for st in self._stations}

    def request(self, station: int, body: Any, *, sub: bool | None = None, timeout_ns: int | None = None,
                now: int | None = None) -> Request:
        """Queue *body* (a wire command body of the station's generation, e.g. ``ml2.PrmRd(0x0200, 2)``).

        Sent in the station's next slots in phase 2/3 (main command, or sub-command with ``sub=True``; ``None``
        picks the sub-command for PRM_RD/PRM_WR on a 32-byte SI-T/V7, V7 §7.1), repeated while CMDRDY /
        SUBCMDRDY reports busy and after a missing response, completed with the decoded response body or failed
        with :class:`StationAlarmError` / :class:`RequestTimeout`. CONNECT and SYNC_SET are the core's own;
        DISCONNECT is :meth:`disconnect`."""
        return self._queue(self._station(station), body, sub, timeout_ns, now)

    # The requests by what they do: each builds its command's body for the station's generation and queues it
    # as :meth:`request` does; *now* and *timeout_ns* as there (docs/master.md, "Requests").
    def prm_rd(self, station: int, register: int | str, size: int = 2, *, sub: bool | None = None,
               timeout_ns: int | None = None, now: int | None = None) -> Request:
        """PRM_RD of a parameter by name (``"C1-01"``; the result is a :class:`~.types.ParamValue`) or of a MEMOBUS
        register by number (the unsigned word for ``size=2``, else the bytes); :class:`~.types.ParamRequestError`
        for an unknown name or a bad register or size, before anything is queued (:mod:`.named`)."""
        st = self._station(station)
        reg, param = named.read_target(st.plan, register, size)
        return self._queue(st, st.codec.prm_rd(reg, size), sub, timeout_ns, now,
                           requests.parameter_result(param, size))

    def prm_wr(self, station: int, register: int | str, value: Any, size: int = 2, *, sub: bool | None = None,
               timeout_ns: int | None = None, now: int | None = None) -> Request:
        """PRM_WR of a parameter by name in engineering units, or of a register by number with a raw int or the
        bytes (:func:`.named.write_target`); :class:`~.types.ParamRequestError` before anything is queued."""
        st = self._station(station)
        reg, data, _ = named.write_target(st.plan, register, value, size)
        return self._queue(st, st.codec.prm_wr(reg, size, data), sub, timeout_ns, now)

    def config(self, station: int, mode: int = 0, *, sub: bool = False, timeout_ns: int | None = None,
               now: int | None = None) -> Request:
        """CONFIG: 0 = enable the written parameters (RAM), 1 = also store them to EEPROM."""
        st = self._station(station)
        return self._queue(st, st.codec.config(mode), sub, timeout_ns, now)

    def id_rd(self, station: int, code: int, offset: int = 0, size: int = 8, *, timeout_ns: int | None = None,
              now: int | None = None) -> Request:
        """ID_RD: the result is *size* bytes of ID *code* from *offset*."""
        st = self._station(station)
        return self._queue(st, st.codec.id_rd(code, offset, size), False, timeout_ns, now,
                           requests.id_result(size))

    def alm_rd(self, station: int, mode: int = 0, index: int = 0, *, sub: bool = False,
               timeout_ns: int | None = None, now: int | None = None) -> Request:
        """ALM_RD: the result is the response body (its ``alm_data``)."""
        st = self._station(station)
        return self._queue(st, st.codec.alm_rd(mode, index), sub, timeout_ns, now)

    def alm_clr(self, station: int, *, timeout_ns: int | None = None, now: int | None = None) -> Request:
        """ALM_CLR mode 0: clear present faults and alarms."""
        st = self._station(station)
        return self._queue(st, st.codec.alm_clr(), False, timeout_ns, now)

    def _queue(self, st: Slave, body: Any, sub: bool | None, timeout_ns: int | None, now: int | None,
               result_of: Callable[[Any], Any] | None = None) -> Request:
        req = requests.build(st, body, sub, self._deadline(timeout_ns, now), result_of)
        if req.kind is Cmd.DISCONNECT and not req.sub:
            return self.disconnect(st.address, timeout_ns=timeout_ns, now=now)
        if not st.enabled:
            req._finish(error=StationDisconnected(f"station {st.address:02X}H is disconnected; connect() it first"))
            return req
        (st.sub_q if req.sub else st.main_q).append(req)
        return req

    def disconnect(self, station: int, *, timeout_ns: int | None = None, now: int | None = None) -> Request:
        """Send DISCONNECT and keep the station in phase 1 (NOP only) until :meth:`connect`."""
        st = self._station(station)
        st.enabled = False
        body = st.codec.disconnect()
        req = Request(station, body, False, Cmd.DISCONNECT.value, st.codec.code_of(body),
                      self._deadline(timeout_ns, now), Cmd.DISCONNECT)
        if st.state in (S.OFFLINE, S.PHASE1):
            req._finish(result=None)
        else:
            st.disconnect_waiters.append(req)
        for q in (st.main_q, st.sub_q):
            while q:
                q.popleft()._finish(error=StationDisconnected(f"station {station:02X}H was disconnected"))
        return req

    def disconnect_all(self, *, timeout_ns: int | None = None, now: int | None = None) -> list[Request]:
        """:meth:`disconnect` of every station that may hold a connection (:data:`~.machine.MAY_HOLD_CONNECTION`):
        what a master does before it stops cycling. The requests complete when the stations answer."""
        return [self.disconnect(st.address, timeout_ns=timeout_ns, now=now) for st in self._stations
                if st.state in MAY_HOLD_CONNECTION]

    def abort_requests(self, message: str = "master stopped") -> int:
        """Fail every queued request (e.g. when the master stops cycling); returns how many."""
        n = 0
        for st in self._stations:
            for q in (st.main_q, st.sub_q, st.disconnect_waiters):
                while q:
                    r = q.pop()
                    r._finish(error=StationDisconnected(f"station {st.address:02X}H: {message}"))
                    n += 1
        return n

    def connect(self, station: int) -> None:
        """Allow (again) bring-up of a station after :meth:`disconnect`."""
        st = self._station(station)
        st.enabled = True

    def _deadline(self, timeout_ns: int | None, now: int | None) -> int:
        base = self._now if now is None else now
        return base + (self.plan.request_timeout_ns if timeout_ns is None else timeout_ns)

    def _station(self, station: int) -> Slave:
        try:
            return self._by_addr[station]
        except KeyError:
            raise KeyError(f"no station {station:02X}H in the plan") from None
