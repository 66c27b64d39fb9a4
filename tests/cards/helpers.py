"""A scripted master for driving the sans-I/O stations with explicit time (shared by tests/cards)."""

from __future__ import annotations

from collections.abc import Hashable
from pathlib import Path
from types import ModuleType
from typing import Any

from mlink_sim.cards import CardOptions, Station, create_card, settings_for
from mlink_sim.wire import Frame, Kind, Link, decode, encode, ml2, ml3

MS = 1_000_000
MASTER = ("192.0.2.1", 50000)
INTRUDER = ("192.0.2.99", 50001)


def station(card: str, *, station: int = 0x21, frame_size: int | None = None, params: tuple[str, ...] = (),
            options: CardOptions | None = None, now: int = 0, eeprom: bytes | None = None,
            link_speed_mbps: int | None = None) -> Station:
    s = settings_for(card, station, frame_size, list(params), link_speed_mbps=link_speed_mbps, options=options)
    return create_card(card, settings=s, now=now, eeprom=eeprom)


class Master:
    """Sends one command per communication cycle: cycle numbers, WDT counts and time advance together."""

    def __init__(self, st: Station, *, tcycle_ns: int = 1 * MS, source: Hashable = MASTER, now: int = 0,
                 finish: bool = True) -> None:
        self.st = st
        self.finish = finish  #: have the card finish after each answer (the I/O layer's part); False: never
        self.link = st.link
        self.size = st.data_size
        self.tcycle_ns = tcycle_ns
        self.source = source
        self.now = now
        self.cycle = 100
        self.count = 0  # master WDT count
        self.slave_echo = 0
        self.last: Frame | None = None

    @property
    def ml3(self) -> bool:
        return self.link is Link.ML3

    def command(self, body: Any, sub: Any = None, *, wdt: int | None = None, cmd_ctrl: int = 0,
                tcycle_ns: int | None = None) -> Frame:
        if self.ml3:
            if sub is None and self.size == 64:
                sub = ml3.Nop()
            msg: Any = ml3.M3Command(body, self._wdt(wdt), cmd_ctrl, sub)
        else:
            if sub is None and self.size == 32:
                sub = ml2.Nop()
            msg = ml2.M2Command(body, self._wdt(wdt), sub)
        return Frame(self.link, Kind.COMMAND, self.st.address, self.cycle,
                     self.tcycle_ns if tcycle_ns is None else tcycle_ns, msg)

    def _wdt(self, wdt: int | None) -> int:
        return ((self.count & 0xF) << 4 | self.slave_echo) if wdt is None else wdt

    def send(self, body: Any, sub: Any = None, *, step: bool = True, **kw: Any) -> Frame | None:
        """Advance one cycle (time, cycle number, WDT count), send, decode the answer; the card finishes what the
        command left for after its answer (``Station.finish``), as the I/O layer has it do (unless made with
        ``finish=False``)."""
        if step:
            self.tick()
        raw = self.st.receive(encode(self.command(body, sub, **kw)), self.source, self.now)
        if self.finish:
            self.st.finish()  # what the I/O layer does once the answer is sent
        if raw is None:
            self.last = None
            return None
        self.last = decode(raw, kind=Kind.RESPONSE)
        self.slave_echo = self.last.message.rwdt & 0xF
        return self.last

    def tick(self, cycles: int = 1) -> None:
        """Let *cycles* communication cycles pass (without sending for all but the last)."""
        self.now += cycles * self.tcycle_ns
        self.cycle += cycles
        self.count += cycles

    # -- bring-up ----------------------------------------------------------------------------------
    def connect(self, *, sync: bool = False, subcmd: bool | None = None, com_tim: int = 1) -> Frame | None:
        sub = (self.size == 64) if subcmd is None and self.ml3 else (self.size == 32 if subcmd is None else subcmd)
        if self.ml3:
            mod = (0x80 if sub else 0) | (0x02 if sync else 0)
            return self.send(ml3.Connect(0x30, mod, com_tim, 0x20))
        ver = 0x10 if self.link is Link.ML1 else 0x21
        mod = (0x80 if sub and ver == 0x21 else 0) | (0x02 if sync else 0)
        return self.send(ml2.Connect(ver, mod, 2 if ver == 0x10 else com_tim))

    def sync_set(self) -> Frame | None:
        return self.send(ml3.SyncSet() if self.ml3 else ml2.SyncSet())

    def nop(self, sub: Any = None, **kw: Any) -> Frame | None:
        return self.send(ml3.Nop() if self.ml3 else ml2.Nop(), sub, **kw)

    def bring_up(self, *, sync: bool = True) -> None:
        assert self.connect() is not None
        if sync:
            assert self.sync_set() is not None
            assert self.st.phase == 3


def alarm(frame: Frame) -> int:
    """MECHATROLINK-II ALARM byte of a response."""
    return frame.message.alarm


def status(frame: Frame) -> int:
    return frame.message.status


def cmd_alm(frame: Frame) -> int:
    return frame.message.stat.cmd_alm


def comm_alm(frame: Frame) -> int:
    return frame.message.stat.comm_alm


def sub_alm(frame: Frame) -> int:
    return frame.message.substat.subcmd_alm


def module_source(module: ModuleType) -> str:
    """A module's source text, read from its .py file: ``inspect.getsource`` has none for a compiled (mypyc)
    module, whose ``__file__`` is the extension module next to the .py."""
    assert module.__file__ is not None
    path = Path(module.__file__)
    if not path.name.startswith("__init__."):
        path = path.with_name(module.__name__.rpartition(".")[2] + ".py")
    return path.read_text(encoding="utf-8")
