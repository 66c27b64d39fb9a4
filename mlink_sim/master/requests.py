"""Requests (PRM_RD, CONFIG, ...): building, completing, timing out (docs/master.md, "Requests").

The core queues a :class:`~mlink_sim.master.types.Request` per station (main and sub-command queues), sends the
head of each queue in the station's phase-2/3 slots and hands every answer and every silence to the functions
here; these touch only the station's queues and the request. A request built for a parameter or an ID carries
what its answer's body gives (:func:`parameter_result`, :func:`id_result`): its result is that value.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

from ..params import Param
from ..wire import Unknown
from . import named
from .codec import command_name
from .commands import Cmd
from .slave import Sent, Slave
from .types import Request, RequestTimeout, StationAlarmError

__all__ = ["build", "complete", "expire", "unanswered", "parameter_result", "id_result", "MANAGED"]

#: Commands the core sends itself (bring-up and recovery); a request for them is refused.
MANAGED = frozenset({Cmd.CONNECT, Cmd.SYNC_SET})


def build(st: Slave, body: Any, sub: bool | None, deadline_ns: int,
          result_of: Callable[[Any], Any] | None = None) -> Request:
    """A request for *body* to station *st* (see :meth:`MasterCore.request`); raises TypeError / ValueError for a
    body that is not a command of the station's generation, a sub-command where the plan has none, or a field
    that does not fit its layout (encoded here once, as a check, so that the cycle never meets a body it cannot
    send; the cycle encodes the frame itself when it sends it). *result_of*: the result the answer's body gives
    (:attr:`Request.result_of`)."""
    codec, plan = st.codec, st.plan
    if sub is None:  # a card that takes PRM_RD/PRM_WR only as sub-commands (V7 §7.1; CardProfile.prm_as_subcommand)
        sub = (codec.prm_as_subcommand and plan.subcmd and type(body) in codec.sub_slot.by_class
               and type(body) in codec.main_slot.by_class
               and codec.kind_of(codec.main_slot.code_of(body)) in (Cmd.PRM_RD, Cmd.PRM_WR))
    if sub and not plan.subcmd:
        raise ValueError(f"station {st.address:02X}H: sub-commands are not enabled in its plan")
    slot = codec.sub_slot if sub else codec.main_slot
    if type(body) is not Unknown and type(body) not in slot.by_class:
        where = "sub-command" if sub else "main command"
        raise TypeError(f"{type(body).__module__}.{type(body).__name__} is not a {plan.link.label} {where}")
    try:  # a field that does not fit is refused here, not when the slot encodes it in the cycle
        code, _ = slot.build(body)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"station {st.address:02X}H: {type(body).__name__} cannot be sent: {exc}") from None
    kind = codec.kind_of(code)
    if kind in MANAGED:
        raise ValueError(f"{kind.value} is sent by the master core itself (bring-up and recovery)")
    return Request(st.address, body, bool(sub), command_name(plan.link, code), code, deadline_ns, kind, result_of)


def parameter_result(param: Param | None, size: int) -> Callable[[Any], Any]:
    """What a PRM_RD answer gives: the first *size* bytes of its PARAMETER field (LSB first) as *param*'s
    :class:`~mlink_sim.master.types.ParamValue`, or for a register read by number (*param* None) the unsigned word
    when *size* is 2, else the bytes (SI-T3 Table 8, SI-ET3 "PRM_RD")."""

    def result(body: Any) -> Any:
        data = bytes(body.parameter[:size])
        if param is not None:
            return named.value_of(param, data)
        return int.from_bytes(data, "little") if size == 2 else data

    return result


def id_result(size: int) -> Callable[[Any], Any]:
    """What an ID_RD answer gives: the first *size* bytes of its ID field (SI-T3 Table 11, SI-ET3 Table 14)."""

    def result(body: Any) -> Any:
        return bytes(body.id[:size])

    return result


def complete(st: Slave, queue: deque[Request], req: Request, code: int | None, ready: bool,
             error: tuple[int, str] | None, body: Any) -> None:
    """An answer to *req*: done (result or :class:`StationAlarmError`), or busy / another command's echo (sent
    again in the next slot)."""
    if req.done:
        return  # already timed out
    req.unanswered = 0
    if error is None and code != req.code:
        return  # the echo is of another command: send it again
    if error is None and not ready:
        req.busy += 1
        return
    if queue and queue[0] is req:
        queue.popleft()
    if error is not None:
        where = "sub-command" if req.sub else "command"
        req._finish(error=StationAlarmError(
            st.address, error[0], error[1],
            f"station {st.address:02X}H refused {req.command} {where}: {error[1]} ({error[0]:02X}H)"))
    else:
        req._finish(result=body if req.result_of is None else req.result_of(body))


def unanswered(st: Slave, sent: Sent, retries: int) -> None:
    """*sent* went unanswered: a round of each request it carried; after *retries* in a row, RequestTimeout."""
    for req, q in ((sent.req, st.main_q), (sent.sub_req, st.sub_q)):
        if req is not None and not req.done:
            req.unanswered += 1
            if req.unanswered >= retries:
                q.remove(req)
                req._finish(error=RequestTimeout(st.address, req.command, req.attempts, req.busy, req.unanswered))


def expire(st: Slave, now: int) -> None:
    """Fail the requests (and disconnect() waiters) past their deadline with :class:`RequestTimeout`."""
    for q in (st.main_q, st.sub_q):
        if q and any(r.deadline_ns <= now for r in q):
            for r in [r for r in q if r.deadline_ns <= now]:
                q.remove(r)
                r._finish(error=RequestTimeout(st.address, r.command, r.attempts, r.busy, r.unanswered))
    waiters = st.disconnect_waiters
    if waiters and any(r.deadline_ns <= now for r in waiters):
        for r in [r for r in waiters if r.deadline_ns <= now]:
            waiters.remove(r)
            r._finish(error=RequestTimeout(st.address, r.command, r.attempts, r.busy))
