"""A minimal slave for the master-core tests, plus an in-memory network with explicit time.

``FakeSlave`` follows the conventions of ``mlink_sim.cards`` (watchdog.py, reception.py, alarms.py, phases.py) closely
enough to exercise the master: phases 1/2/3, the WDT rule "master count advances by the communication cycles
elapsed", reception failures 96 -> E6 (SI-T3 Table 22) / COMM_ALM 2 -> 9 (SI-ET3), phase 3 -> 2 on a fault,
A.94/A.95 and CMD_ALM, CMDRDY busy on CONFIG, ML-III NOP in phase 1 = phase error (SI-ET3 Table 9).
The tests take their slave from the ``slave_factory`` fixture so they can run against the real cards too.

``Net`` is a discrete-event loopback (pymodbus NullModem style): datagrams are delivered after a latency, and
a ``fault`` hook can drop, delay or corrupt any of them.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable
from typing import Any

from mlink_sim.master import MasterCore
from mlink_sim.wire import (
    CmdAlm,
    CommAlm,
    Frame,
    Kind,
    Link,
    M2Alarm,
    M2ComMod,
    M2Status,
    M2SubStatus,
    M3ComMod,
    WireError,
    decode,
    encode,
    ml2,
    ml3,
)

MS = 1_000_000

#: (link, transmission cycle, COM_TIM) of the bring-up tests: ML-I VER 10H COM_TIM 2 on its fixed 2 ms cycle
#: (SI-T3 errata (2)), ML-II VER 21H COM_TIM 1 (SI-T3 errata (1)), ML-III VER 30H.
GENERATION_CASES = [
    (Link.ML1, 2 * MS, 2),
    (Link.ML2, 1 * MS, 1),
    (Link.ML3, 1 * MS, 1),
]
GENERATION_IDS = ["ML-I-VER10H-COM_TIM2", "ML-II-VER21H-COM_TIM1", "ML-III-VER30H"]
_PHASE2_PLUS = {"PRM_WR", "CONFIG", "ALM_CLR", "SYNC_SET", "INV_CTL"}


class FakeSlave:
    """One station: ``receive(datagram, source, now) -> bytes | None`` and ``poll(now)``."""

    def __init__(self, link: Link, address: int, data_size: int, *, registers: dict[int, int] | None = None,
                 busy_config: int = 2, et3_table19: bool = True) -> None:
        self.link = link
        self.address = address
        self.data_size = data_size
        self.mod = ml3 if link is Link.ML3 else ml2
        self.registers = dict(registers if registers is not None else {0x0200: 100, 0x0180: 3, 0x0181: 3})
        self.busy_config = busy_config
        self.et3_table19 = et3_table19
        self.phase = 1
        self.cpc = 1
        self.comm_ns = 2 * MS
        self.last_cycle: int | None = None
        self.silence_deadline: int | None = None
        self.consecutive = 0
        self.wdt_master = 0
        self.wdt_armed = False
        self.slave_count = 0
        self.comm_alarm = 0  # ML-II E5/E6 latched; ML-III COMM_ALM latched
        self.one_shot: set[int] = set()  # ML-II communications warnings reported once
        self.config_left = 0
        self.speed = 0
        self.forward = False
        self.log: list[tuple[str, int]] = []  # (command name, phase) received
        self.e5 = 0
        self.failures = 0
        self.failures_since_rx = 0  # found by silence or bad FCS, not to be counted again by the next gap
        self._elapsed = 1  # communication cycles since the previous command
        self._tcycle = MS

    # ------------------------------------------------------------------ reception
    def receive(self, datagram: bytes, source: Any, now: int) -> bytes | None:
        try:
            frame = decode(datagram, kind=Kind.COMMAND)
        except WireError:
            if self.phase >= 2:
                self.failures_since_rx += 1
                self._fail(1, fcs=True)
            return None
        if frame.station != self.address or frame.data_size != self.data_size or frame.link is not self.link:
            return None
        msg = frame.message
        if self.phase >= 2:
            self._gap(frame.cycle)
        self.last_cycle = frame.cycle
        self.silence_deadline = now + self.comm_ns + max(self.comm_ns // 2, MS)
        self.consecutive = 0
        name = self._name(msg.code)
        self.log.append((name, self.phase))
        if self.phase == 3 and name != "DISCONNECT":
            count = (msg.wdt >> 4) & 0xF
            if self.wdt_armed and count != (self.wdt_master + self._elapsed) & 0xF:
                self.e5 += 1
                self._alarm(0xE5 if self.link is not Link.ML3 else CommAlm.WDT_ERROR)
            self.wdt_master = count
            self.wdt_armed = True
        else:
            self.wdt_master = (msg.wdt >> 4) & 0xF
        body, status, err = self._main(name, msg)
        sub = sub_status = None
        if msg.sub is not None:
            sub, sub_status = self._sub(self._name(self.mod.COMMAND_SUB.code_of(msg.sub)), msg.sub)
        self.slave_count = (self.slave_count + 1) & 0xF
        rwdt = self.slave_count | (self.wdt_master << 4)
        if self.link is Link.ML3:
            stat = ml3.CmdStat(cmdrdy=status, cmd_alm=err, comm_alm=self.comm_alarm).to_int()
            resp: Any = ml3.M3Response(body, rwdt, stat, sub, sub_status or 0)
        else:
            alarm, st = self._ml2_alarm(err)
            st |= M2Status.CMDRDY if status else 0
            resp = ml2.M2Response(body, alarm, int(st), rwdt, sub, sub_status or 0)
        return encode(Frame(self.link, Kind.RESPONSE, self.address, frame.cycle, frame.tcycle_ns, resp))

    def _gap(self, cycle: int) -> None:
        if self.last_cycle is None:
            return
        delta = (cycle - self.last_cycle) & 0xFFFFFFFF
        self._elapsed = max(1, (delta + self.cpc // 2) // self.cpc)
        for _ in range(max(0, self._elapsed - 1 - self.failures_since_rx)):
            self._fail(1)
        self.failures_since_rx = 0

    def poll(self, now: int) -> None:
        if self.phase < 2 or self.silence_deadline is None or now < self.silence_deadline:
            return
        n = (now - self.silence_deadline) // self.comm_ns + 1
        self.silence_deadline += n * self.comm_ns
        self.failures_since_rx += n
        self._fail(n)

    def _fail(self, n: int, fcs: bool = False) -> None:
        for _ in range(n):
            self.failures += 1
            first = self.consecutive == 0
            self.consecutive += 1
            if self.link is Link.ML3:
                if first:
                    if self.comm_alarm < 8:
                        self.comm_alarm = CommAlm.FCS_WARNING if fcs else CommAlm.NOT_RECEIVED_WARNING
                else:
                    self._alarm(CommAlm.FCS_ERROR if fcs else CommAlm.NOT_RECEIVED)
            elif first:
                self.one_shot.add(M2Alarm.COMM_WARNING)
            else:
                self._alarm(M2Alarm.COMM_ERROR)

    def _alarm(self, code: int) -> None:
        self.comm_alarm = code
        if self.phase == 3:
            self.phase = 2
            self.wdt_armed = False

    # ------------------------------------------------------------------ commands
    def _name(self, code: int) -> str:
        cmd = self.mod.COMMAND_MAIN.by_code.get(code)
        return cmd.cls.__name__ if cmd else f"{code:02X}H"

    def _main(self, name: str, msg: Any) -> tuple[Any, bool, int]:
        """(response body, CMDRDY, error: ML-II alarm code / ML-III CMD_ALM)."""
        m = self.mod
        ml3_link = self.link is Link.ML3
        phase_err = CmdAlm.PHASE_ERROR if ml3_link else M2Alarm.COMMAND_WARNING
        body = msg.body
        key = {"PrmRd": "PRM_RD", "PrmWr": "PRM_WR", "Config": "CONFIG", "AlmClr": "ALM_CLR", "SyncSet": "SYNC_SET",
               "InvCtl": "INV_CTL", "Connect": "CONNECT", "Disconnect": "DISCONNECT", "Nop": "NOP", "IdRd": "ID_RD",
               "AlmRd": "ALM_RD"}.get(name, name)
        if key == "CONNECT":
            if self.phase != 1:
                return body, True, 0  # ignored, no alarm (SI-T3 "CONNECT"; SI-ET3 Table 9 △)
            return self._connect(body)
        if self.phase == 1 and (ml3_link and key != "DISCONNECT" or key in _PHASE2_PLUS):
            return self._echo(key, body), True, phase_err
        if key == "DISCONNECT":
            if self.phase != 1:
                self.phase = 1
                self.comm_alarm = 0
                self.wdt_armed = False
            return body, True, 0
        if key == "SYNC_SET":
            if self.phase == 2:
                self.phase = 3
                self.wdt_armed = False
            return body, True, 0
        if key == "ALM_CLR":
            self.comm_alarm = 0
            self.one_shot.clear()
            return body, True, 0
        if key == "INV_CTL":
            if ml3_link:
                self.forward = bool(body.invcmd_ctrl & 1)
                stat = (1 if self.forward else 0) | 0x8 | 0x40
                return ml3.InvCtlResponse(stat, 0, body.speed_ref if self.forward else 0, 12, body.sel_ref,
                                          body.sel_mon, 0, 0), True, 0
            self.forward = bool(body.signals & 1)
            return ml2.InvCtlResponse(body.speed_ref if self.forward else 0, 12, body.sel_ref, body.sel_mon, 0,
                                      0), True, 0
        if key in ("PRM_RD", "PRM_WR"):
            return self._prm(key, body)
        if key == "CONFIG":
            if body.config_mod not in (0, 1):
                return body, True, (CmdAlm.INVALID_DATA if ml3_link else M2Alarm.DATA_SETTING_WARNING)
            if self.config_left == 0:
                self.config_left = self.busy_config + 1
            self.config_left -= 1
            return body, self.config_left == 0, 0
        if key == "ID_RD":
            data = b"CIMR-AU4A0002".ljust(24, b"\0")[body.offset: body.offset + body.size]
            if ml3_link and body.id_code == 0x10:
                data = (0x20).to_bytes(4, "little")  # SI-ET3 Table 14 ID_CODE 10H
            if ml3_link:
                return ml3.IdRdResponse(body.id_code, body.offset, body.size, data.ljust(24, b"\0")), True, 0
            return ml2.IdRdResponse(body.device_code, body.offset, body.size, data[:8].ljust(8, b"\0")), True, 0
        if key == "ALM_RD":
            if ml3_link:
                return ml3.AlmRdResponse(body.alm_rd_mod, body.alm_index, bytes(20)), True, 0
            return ml2.AlmRdResponse(body.alm_rd_mod, bytes(10)), True, 0
        if key == "NOP":
            return body, True, 0
        return m.Nop(), True, (CmdAlm.UNSUPPORTED_COMMAND if ml3_link else M2Alarm.COMMAND_WARNING)

    def _echo(self, key: str, body: Any) -> Any:
        if key in ("PRM_RD",):
            return self.mod.PrmRdResponse(body.no, body.size)
        if key == "INV_CTL":
            return (ml3.InvCtlResponse() if self.link is Link.ML3 else ml2.InvCtlResponse())
        if key in ("ID_RD", "ALM_RD"):
            return self.mod.Nop()
        return body

    def _connect(self, body: Any) -> tuple[Any, bool, int]:
        ml3_link = self.link is Link.ML3
        bad = CmdAlm.INVALID_DATA if ml3_link else M2Alarm.DATA_SETTING_WARNING
        want_ver = {Link.ML1: 0x10, Link.ML2: 0x21, Link.ML3: 0x30}[self.link]
        reserved = M3ComMod.RESERVED if ml3_link else M2ComMod.RESERVED
        if body.ver != want_ver or body.com_mod & reserved or not 1 <= body.com_tim <= 255:
            return body, True, bad
        if ml3_link and body.profile_type != 0x20:
            return body, True, bad
        if self.link is Link.ML2 and body.com_tim != 1:
            return body, True, bad  # SI-T3 errata (1)
        if self.link is Link.ML1 and body.com_tim != 2:
            return body, True, bad  # SI-T3 errata (2)
        sub_ok = self.data_size == (64 if ml3_link else 32)
        if body.com_mod & 0x80 and not sub_ok:
            return body, True, bad
        sync_bit = bool(body.com_mod & 0x02)
        sync = (not sync_bit) if (ml3_link and self.et3_table19) else sync_bit
        self.phase = 3 if sync else 2
        self.cpc = 1 if self.link is Link.ML1 else body.com_tim
        self.comm_ns = (body.com_tim * MS) if self.link is Link.ML1 else body.com_tim * self._tcycle
        self.wdt_armed = False
        self.consecutive = 0
        return body, True, 0

    def _prm(self, key: str, body: Any) -> tuple[Any, bool, int]:
        ml3_link = self.link is Link.ML3
        bad = (CmdAlm.INVALID_DATA if ml3_link else M2Alarm.DATA_SETTING_WARNING)
        regs = [body.no + i for i in range(body.size // 2)]
        ok = body.size in (2, 4, 6, 8) and all(r in self.registers for r in regs)
        if key == "PRM_RD":
            if not ok:
                return self.mod.PrmRdResponse(body.no, body.size), True, bad
            data = b"".join(self.registers[r].to_bytes(2, "little") for r in regs).ljust(8, b"\0")
            return self.mod.PrmRdResponse(body.no, body.size, data), True, 0
        if not ok:
            return body, True, bad
        for i, r in enumerate(regs):
            self.registers[r] = int.from_bytes(body.data[2 * i: 2 * i + 2], "little")
        return body, True, 0

    def _sub(self, name: str, sub: Any) -> tuple[Any, int]:
        ml3_link = self.link is Link.ML3
        key = {"PrmRd": "PRM_RD", "PrmWr": "PRM_WR"}.get(name, name)
        if key in ("PRM_RD", "PRM_WR") and self.phase >= 2:
            body, _, err = self._prm(key, sub)
            if ml3_link:
                return body, ml3.SubStat(True, err).to_int()
            if err:
                self.one_shot.add(err)
                return body, int(M2SubStatus.SUBCMDRDY | M2SubStatus.SUBWARNG)
            return body, int(M2SubStatus.SUBCMDRDY)
        if ml3_link:
            return ml3.Nop(), ml3.SubStat().to_int()
        return ml2.Nop(), int(M2SubStatus.SUBCMDRDY)

    def _ml2_alarm(self, err: int) -> tuple[int, M2Status]:
        """SI-T3 Table 21: the most recent alarm wins; else the lowest warning; reported warnings drop."""
        warnings = set(self.one_shot)
        self.one_shot.clear()
        if err:
            warnings.add(err)
        if self.comm_alarm:
            return self.comm_alarm, M2Status.ALM | (M2Status.WARNG if warnings else M2Status(0))
        if warnings:
            return min(warnings), M2Status.WARNG
        return 0, M2Status(0)


SlaveFactory = Callable[[Link, int, int], Any]


def fake_factory(tcycle_ns: int) -> SlaveFactory:
    def make(link: Link, address: int, data_size: int, **kw: Any) -> FakeSlave:
        s = FakeSlave(link, address, data_size, **kw)
        s._tcycle = tcycle_ns
        return s

    return make


class CardSlave:
    """A real ``mlink_sim.cards`` station (SI-T3 for ML-I/II, SI-ET3 for ML-III) with the few read-outs the tests
    use on :class:`FakeSlave`: ``phase``, ``log`` (command names received), ``e5`` (WDT errors), ``failures``."""

    def __init__(self, link: Link, address: int, data_size: int, *, et3_table19: bool = True, **kw: Any) -> None:
        from mlink_sim.cards import CardOptions, create_card, settings_for

        if kw:
            raise TypeError(f"option(s) {sorted(kw)} exist on the fake slave only")
        if link is Link.ML3:
            settings = settings_for("si-et3", address, data_size, [],
                                    options=CardOptions(et3_syncmode_table19=et3_table19))
            self.station = create_card("si-et3", settings=settings, now=0)
        else:
            settings = settings_for("si-t3", address, data_size, [], link_speed_mbps=4 if link is Link.ML1 else 10)
            self.station = create_card("si-t3", settings=settings, now=0)
        self.link = link
        self.mod = ml3 if link is Link.ML3 else ml2
        self.log: list[tuple[str, int]] = []

    def receive(self, datagram: bytes, source: Any, now: int) -> bytes | None:
        try:
            frame = decode(datagram, kind=Kind.COMMAND)
        except WireError:
            pass
        else:
            if frame.station == self.station.address:
                self.log.append((type(frame.message.body).__name__, self.station.phase))
        return self.station.receive(datagram, source, now)

    def poll(self, now: int) -> None:
        self.station.poll(now)

    @property
    def phase(self) -> int:
        return self.station.phase

    @property
    def e5(self) -> int:
        return self.station.counters.wdt_errors

    @property
    def failures(self) -> int:
        return self.station.counters.reception_failures


def card_factory(tcycle_ns: int) -> SlaveFactory:
    def make(link: Link, address: int, data_size: int, **kw: Any) -> CardSlave:
        return CardSlave(link, address, data_size, **kw)

    return make


class Net:
    """In-memory network between one MasterCore and its slaves, on explicit time.

    Each transmission cycle *k* starts at ``k * tcycle``: the master's datagrams are delivered after
    ``latency_ns``, responses after another ``latency_ns``; slaves are polled at every delivery and at the
    end of the cycle. ``fault(direction, station, datagram, now)`` returns the datagram (possibly altered),
    None to drop it, or ``(datagram, extra_delay_ns)``; direction is "cmd" or "rsp".
    """

    def __init__(self, core: MasterCore, slaves: dict[int, Any], *, latency_ns: int = 20_000) -> None:
        self.core = core
        self.slaves = slaves
        self.tcycle = core.plan.tcycle_ns
        self.latency = latency_ns
        self.cycle = 0
        self.fault: Callable[[str, int, bytes, int], Any] | None = None
        self.cut: set[int] = set()  # stations unplugged (both directions)
        self._queue: list[tuple[int, int, str, int, bytes]] = []
        self._seq = 0
        self.events: list[Any] = []

    def _send(self, direction: str, station: int, datagram: bytes, now: int) -> None:
        if station in self.cut:
            return
        delay = self.latency
        if self.fault is not None:
            res = self.fault(direction, station, datagram, now)
            if res is None:
                return
            if isinstance(res, tuple):
                datagram, extra = res
                delay += extra
            else:
                datagram = res
        self._seq += 1
        heapq.heappush(self._queue, (now + delay, self._seq, direction, station, datagram))

    def run(self, cycles: int) -> None:
        for _ in range(cycles):
            k = self.cycle
            now = k * self.tcycle
            for station, datagram in self.core.on_cycle(k, now):
                self._send("cmd", station, datagram, now)
            end = now + self.tcycle
            while self._queue and self._queue[0][0] < end:
                at, _, direction, station, datagram = heapq.heappop(self._queue)
                if direction == "cmd":
                    slave = self.slaves.get(station)
                    if slave is None:
                        continue
                    resp = slave.receive(datagram, "master", at)
                    slave.poll(at)
                    if resp is not None:
                        self._send("rsp", station, resp, at)
                else:
                    self.core.on_response(datagram, at)
            for slave in self.slaves.values():
                slave.poll(end - 1)
            self.events.extend(self.core.drain_events())
            self.cycle += 1

    def run_until(self, predicate: Callable[[], bool], limit: int = 2000) -> int:
        """Run cycles until *predicate()*; returns the number of cycles run (fails the test past *limit*)."""
        for n in range(1, limit + 1):
            self.run(1)
            if predicate():
                return n
        raise AssertionError(f"condition not reached in {limit} cycles; states {self.core.views()}")
