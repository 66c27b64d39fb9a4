"""The master's per-cycle INV_CTL exchange straight from and to bytes (the steady state of a phase-3 network).

Once a station is up, almost every slot is the same cyclic INV_CTL command (SI-T3 Table 16, SI-ET3 Table 20,
SI-T/V7 Table 3) answered by an INV_CTL response without alarm or warning. The general path builds a
:class:`~mlink_sim.wire.Frame` and message objects for it, then a :class:`~mlink_sim.master.codec.Reply`, and
runs the phase machine: several times the CPU of the bytes-to-bytes exchange here, per station and cycle, which
would limit the stations a small machine carries at 1 ms to a fraction of the targets (docs/performance.md, "The
capacity targets"; "Compiled cores" has the cost of one exchange).

:class:`CyclicFrames` does the same exchange with ``struct`` formats that are derived mechanically from the wire
declarations. Nothing here is declared a second time:

* **command**: the datagram of the station's current INV_CTL body is encoded once by the general encoder
  (:func:`mlink_sim.wire.encode`) with cycle 0 and WDT 0. Each slot copies it, patches the cycle number
  (envelope bytes 4–7) and the WDT byte (data byte 15 on ML-I/II, byte 1 on ML-III; offsets from
  ``COMMAND_FRAME_*``) and appends the FCS (:func:`~mlink_sim.wire.frame.patch_seal`: one C call with the
  compiled cores).
* **response**: one ``unpack_from`` of the whole datagram: the envelope, the data frame (``RESPONSE_FRAME_*``)
  and the INV_CTL response body (``RESPONSE_MAIN``) in one format (:func:`~mlink_sim.wire.frame.datagram_struct`).

:meth:`CyclicFrames.response` returns -1 (not an RWDT) for anything that is not a clean INV_CTL answer, e.g. a
non-zero ALARM byte or STATUS.ALM/WARNG (ML-II), CMD_STAT ALM or CMD_ALM or a COMM_ALM edge (ML-III), another
code, a bad FCS or another size. The core then takes the general path, so alarms, phase errors and malformed
input are all handled in one place. Which command an answer is for (on time or late) the core decides for both
paths in one place (:mod:`.answers`). tests/master/test_master_fastpath.py checks that both paths
give the same bytes, views and events.
"""

from __future__ import annotations

from operator import itemgetter
from typing import Any, Final

from ..wire import Frame, Kind, Link, encode, ml2, ml3
from ..wire.codes import M2Cmd, M2Status, M3Cmd
from ..wire.frame import (
    CYCLE_AT, FCS_SIZE, HEADER_SIZE, MAGIC, datagram_offset, datagram_struct, fcs_ok, patch_seal, steady_delta,
)
from .codec import Codec
from .plan import StationPlan

__all__ = ["CyclicFrames"]


#: ML-II STATUS ALM and WARNG (bits 0/1, SI-T3 "STATUS Field", an unnumbered table) and the ALARM byte must be
#: zero for the fast path.
_ML2_TROUBLE: Final = int(M2Status.ALM | M2Status.WARNG)
#: ML-III CMD_STAT (SI-ET3 §8 "Command Status (CMD_STAT)", an unnumbered table): D_ALM (bit 0) and CMD_ALM
#: (bits 8-11) must be zero; COMM_ALM (bits 12-15) must not change (a latched warning 1-7 may stay; 8 and up is an
#: alarm, and an edge is an event).
_ML3_ALARMS: Final = 0x0F01


def _frames(link: Link, size: int) -> tuple[Any, Any, int, Any]:
    """(command frame declaration, response frame declaration, INV_CTL code, response body layout)."""
    if link is Link.ML3:
        cmd = ml3.COMMAND_FRAME_32 if size == 32 else ml3.COMMAND_FRAME_64
        rsp = ml3.RESPONSE_FRAME_32 if size == 32 else ml3.RESPONSE_FRAME_64
        return cmd, rsp, M3Cmd.INV_CTL, ml3.RESPONSE_MAIN.by_code[M3Cmd.INV_CTL]
    cmd = ml2.COMMAND_FRAME_17 if size == 17 else ml2.COMMAND_FRAME_32
    rsp = ml2.RESPONSE_FRAME_17 if size == 17 else ml2.RESPONSE_FRAME_32
    return cmd, rsp, M2Cmd.INV_CTL, ml2.RESPONSE_MAIN.by_code[M2Cmd.INV_CTL]


class CyclicFrames:
    """Encode the cyclic INV_CTL command and decode its clean response for one station (see module docstring)."""

    __slots__ = ("link", "address", "size", "_codec", "_tcycle", "_wdt_at", "_body", "_template", "_dg", "_code",
                 "_status_at", "_alarm_at", "_ml3", "_pick", "_unpack", "_rwdt_at", "_last", "last", "_last_comm")

    def __init__(self, plan: StationPlan, tcycle_ns: int, codec: Codec) -> None:
        link, size = plan.link, plan.data_size
        cmd, rsp, code, main = _frames(link, size)
        self.link = link
        self.address = plan.address
        self.size = HEADER_SIZE + size + FCS_SIZE
        self._codec = codec
        self._tcycle = tcycle_ns
        self._wdt_at = datagram_offset("wdt", cmd)
        self._rwdt_at = datagram_offset("rwdt", rsp)
        # the last clean response taken (response()) and the COMM_ALM it was judged against
        self._last = b""
        self._last_comm = 0
        #: ``(status, output_freq, output_current, mon1, mon2, warning)`` of the last clean response taken
        self.last: tuple[int, int, int, int, int, bool] = (0, 0, 0, 0, 0, False)
        self._body: Any = None
        self._template = bytearray()
        # the whole response (envelope, frame, INV_CTL body) in one struct: one unpack per datagram
        self._dg, names = datagram_struct(rsp, size, main=(main.struct.subcon, main.size))
        self._unpack = self._dg.unpack_from
        self._code = int(code)
        self._ml3 = link is Link.ML3
        self._status_at = names.index("cmd_stat" if self._ml3 else "status")
        self._alarm_at = None if self._ml3 else names.index("alarm")
        # (rwdt, STATUS, output_freq, output_current, mon1, mon2): the station's STATUS as the general path keeps
        # it, ML-III INVCMD_STAT of the body, ML-II the STATUS word
        self._pick = itemgetter(*(names.index(n) for n in ("rwdt", "invcmd_stat" if self._ml3 else "status",
                                                           "output_freq", "output_current", "mon1", "mon2")))

    # ------------------------------------------------------------------ command
    def command(self, body: Any, cycle: int, wdt: int) -> bytes:
        """Datagram of the cyclic command *body* (the INV_CTL of the station's control) for *cycle* (u32)."""
        tpl = self._template
        if body is not self._body:  # a new control: one datagram through the general encoder is the template
            message = self._codec.message(body, 0, None)
            tpl = self._template = bytearray(encode(Frame(self.link, Kind.COMMAND, self.address, 0, self._tcycle,
                                                          message))[:-FCS_SIZE])
            self._body = body
        return patch_seal(tpl, CYCLE_AT, cycle, self._wdt_at, wdt)

    # ------------------------------------------------------------------ response
    def response(self, dg: bytes, cycle: int, comm_alm: int) -> int:
        """The RWDT of a clean INV_CTL response to the command of *cycle*, its other fields in :attr:`last`; or -1:
        the general path decides (see module docstring). An int and a kept tuple, not a new tuple per answer: this
        runs for every answer of every cycle.

        *comm_alm* is the station's COMM_ALM as last seen (ML-III): a response keeping the same communication
        warning (COMM_ALM 1-7, latched until ALM_CLR) is still clean, any change goes the general way.

        In the steady state, a response that differs from the last clean one only in its cycle (the one asked
        for), RWDT and FCS (:func:`~mlink_sim.wire.frame.steady_delta`, one C call) gives what the last one gave
        (:attr:`last` unchanged) with its RWDT, without being unpacked and checked field by field again."""
        last = self._last
        if last:
            d = steady_delta(dg, last, CYCLE_AT, self._rwdt_at)
            if d >= 0 and d & 0xFFFFFFFF == cycle and comm_alm == self._last_comm:
                return d >> 32
        if len(dg) != self.size:
            return -1
        f = self._unpack(dg)
        if (f[0] != MAGIC or f[1] != self.link or f[2] != 2 or f[3] != self.address or f[4] != cycle
                or f[6] != self._code):
            return -1
        cstat = f[self._status_at]
        if self._ml3:
            if cstat & _ML3_ALARMS or cstat >> 12 != comm_alm:
                return -1
        elif cstat & _ML2_TROUBLE or f[self._alarm_at]:  # type: ignore[index]  # an int on II (None: III)
            return -1
        if not fcs_ok(dg):
            return -1
        picked: tuple[int, int, int, int, int, int] = self._pick(f)
        self.last = picked[1:] + (bool(cstat & 2),)
        self._last, self._last_comm = dg, comm_alm
        return picked[0]
