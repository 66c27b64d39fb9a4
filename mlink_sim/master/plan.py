"""What the master is told to do: one :class:`StationPlan` per slave, gathered in a :class:`NetworkPlan`.

Pure data, validated on construction (``ValueError`` with a complete sentence). The ranges checked here are the
*network* rules of the manuals; rules of one particular card (e.g. the SI-T3 errata's COM_TIM = 1 on
MECHATROLINK-II) are left to the card, which answers A.94 and lets the master report it.

Communication cycle (the period at which one station is served):

* MECHATROLINK-II/III: ``COM_TIM`` x transmission cycle (SI-T3 "CONNECT" COM_TIM; SI-ET3 CONNECT byte 6
  "Sets multiples of the transmission cycle as the communication cycle").
* MECHATROLINK-I (VER 10H): COM_TIM counts milliseconds on a transmission cycle fixed at 2 ms
  (SI-T3 errata (2): "COM_TIM = 2 the units for COM_TIM were 1 = 1 ms and transmission cycles were fixed at
  2 ms"; SI-T/V7 §7.1 "2 [ms] <= COM_TIM <= 64 [ms]"), so COM_TIM 2 is one transmission cycle.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..profiles import CardProfile, lookup
from ..wire import ConnectVersion, Link, M2ComMod, M3ComMod, PROFILE_TYPE_INVERTER

__all__ = ["StationPlan", "NetworkPlan", "TCYCLE_RANGE_NS"]

_US = 1_000
_MS = 1_000_000

#: Transmission-cycle range per generation: SI-T3 "Specifications" (500 us to 8 ms; MECHATROLINK-I fixed at 2 ms,
#: SI-T3 errata (2)); SI-ET3 Table 14 ID_CODE 16H/17H (250 us to 8 ms).
TCYCLE_RANGE_NS: dict[Link, tuple[int, int]] = {
    Link.ML1: (2 * _MS, 2 * _MS),
    Link.ML2: (500 * _US, 8 * _MS),
    Link.ML3: (250 * _US, 8 * _MS),
}

_DEFAULT_SIZE = {Link.ML1: 17, Link.ML2: 32, Link.ML3: 64}
_VERSION = {Link.ML1: ConnectVersion.ML1, Link.ML2: ConnectVersion.ML2, Link.ML3: ConnectVersion.ML3}


@dataclass(frozen=True, slots=True)
class StationPlan:
    """How the master drives one slave station."""

    address: int
    """Station address (envelope byte 3); 03H–EFH on SI-ET3 (Table 7, F6-20), 21H… on SI-T3."""

    link: Link
    """Generation of the network; must equal :attr:`NetworkPlan.link`."""

    data_size: int = 0
    """Frame data size: 17 (ML-I), 17/32 (ML-II), 32/64 (ML-III). 0 = the card's factory setting (its profile's
    first size on the link); without a card named, 17 on ML-I, 32 on ML-II (SI-T3 F6-21 = 0), 64 on ML-III (SI-ET3
    Table 7, F6-21 default 0 = 64-byte)."""

    com_tim: int = 0
    """CONNECT COM_TIM. ML-II/III: communication cycle in transmission cycles (1–32 / 1–255); ML-I: milliseconds
    (2–64, a multiple of the 2 ms transmission cycle). 0 = default (ML-I 2, else 1)."""

    sync: bool = True
    """Bring the station to phase 3 (synchronous; CONNECT SYNCMOD + SYNC_SET) rather than stop in phase 2."""

    subcmd: bool = False
    """Set COM_MOD.SUBCMD and allow sub-command requests; only with 32-byte ML-II or 64-byte ML-III frames."""

    name: str = ""
    """Informational label used in logs and views."""

    card: str = ""
    """The station's card, any spelling of a registered one (read as its key, "si-t-v7"; :mod:`mlink_sim.profiles`);
    "" = not known. Its profile picks the drive code tables for names, the parameter table, the combination table,
    the motor speed monitor and where PRM_RD/PRM_WR go (a 32-byte SI-T/V7 takes them only as sub-commands, V7
    §7.1)."""

    et3_syncmode_table19: bool = False
    """ML-III only. SI-ET3 Table 19 reads COM_MOD.SYNCMODE 0 = synchronous, 1 = asynchronous – the reverse of
    the MECHATROLINK-II manuals. False (default, the same default as the cards' ``CardOptions``) encodes
    1 = synchronous as the MECHATROLINK-II manuals do; True encodes COM_MOD by Table 19. Either way a
    synchronous station also receives SYNC_SET, so it reaches phase 3 (docs/cards.md, "Ambiguities")."""

    speed_search: bool = False
    """The drive catches a motor that still turns when it is run (A1000 b3-01 = 1, or a speed-search input,
    docs/drive-model.md §10). After a recovery the master then runs it again at once; without, it waits for
    standstill (docs/master.md, "Running again after a recovery")."""

    standstill: int = 120
    """|U1-05 motor speed| (MON1, in the drive's o1-03 units) at or below which the restart rule takes the motor
    for stopped: 2 % of the maximum output frequency (E1-04), mlink-sim's choice (docs/master.md); the default
    is 1.2 Hz at E1-04 = 60 Hz and o1-03 = 0 (0.01 Hz)."""

    hz_per_count: float = 0.0
    """Hz of one count of the output frequency and speed reference in the drive's units (o1-03 / n035: 0.01 at
    their defaults); the views' ``output_hz`` reads it. 0 = not known (``output_hz`` is then None)."""

    search_input: int = 0
    """``Control.multi_inputs`` bits of a speed-search command terminal (VS-606V7 n052–n056 = 14/15): on with
    the run command after a recovery until speed agree."""

    def __post_init__(self) -> None:
        link = Link(self.link)
        object.__setattr__(self, "link", link)
        sizes: tuple[int, ...] = ()
        if self.card:
            profile = lookup(self.card)  # ValueError listing the cards
            object.__setattr__(self, "card", profile.key)
            sizes = profile.frames.get(link.name, ())
        if not 0 <= self.address <= 0xFF:
            raise ValueError(f"station address {self.address} does not fit one byte (0–255)")
        size = self.data_size or (sizes[0] if sizes else _DEFAULT_SIZE[link])
        object.__setattr__(self, "data_size", size)
        if size not in link.data_sizes:
            allowed = " or ".join(map(str, link.data_sizes))
            raise ValueError(f"station {self.address:02X}H: {size}-byte frames do not exist on {link.label} "
                             f"({allowed})")
        com_tim = self.com_tim or (2 if link is Link.ML1 else 1)
        object.__setattr__(self, "com_tim", com_tim)
        lo, hi = {Link.ML1: (2, 64), Link.ML2: (1, 32), Link.ML3: (1, 255)}[link]
        if not lo <= com_tim <= hi:
            raise ValueError(f"station {self.address:02X}H: COM_TIM {com_tim} is outside {lo}–{hi} on {link.label}")
        if link is Link.ML1 and com_tim % 2:
            raise ValueError(f"station {self.address:02X}H: MECHATROLINK-I COM_TIM counts ms on a 2 ms transmission "
                             f"cycle and must be even, got {com_tim}")
        if self.subcmd and size != {Link.ML1: 0, Link.ML2: 32, Link.ML3: 64}[link]:
            raise ValueError(f"station {self.address:02X}H: sub-commands need 32-byte MECHATROLINK-II or 64-byte "
                             f"MECHATROLINK-III frames, not {size}-byte {link.label}")

    @property
    def ver(self) -> int:
        """CONNECT VER: 10H (ML-I), 21H (ML-II), 30H (ML-III)."""
        return int(_VERSION[self.link])

    @property
    def profile_type(self) -> int:
        """CONNECT PROFILE_TYPE (ML-III only): 20H, the standard inverter profile."""
        return PROFILE_TYPE_INVERTER

    @property
    def com_mod(self) -> int:
        """CONNECT COM_MOD: SYNCMOD/SYNCMODE per :attr:`sync`, DTMOD 00 (single transfer), SUBCMD per :attr:`subcmd`
        (SI-T3 "CONNECT" COM_MOD; SI-ET3 Tables 18/19)."""
        if self.link is Link.ML3:
            sync_bit = (not self.sync) if self.et3_syncmode_table19 else self.sync
            return (int(M3ComMod.SYNCMODE) if sync_bit else 0) | (int(M3ComMod.SUBCMD) if self.subcmd else 0)
        return (int(M2ComMod.SYNCMOD) if self.sync else 0) | (int(M2ComMod.SUBCMD) if self.subcmd else 0)

    @property
    def has_sub(self) -> bool:
        """Frames carry a sub-command area (32-byte ML-II, 64-byte ML-III), used or not."""
        return self.data_size == (32 if self.link is not Link.ML3 else 64)

    @property
    def profile(self) -> CardProfile | None:
        """The profile of the card the plan names (:mod:`mlink_sim.profiles`), None when it names none. Looked up by
        name: read it once, where a station's codec or record is made."""
        return lookup(self.card) if self.card else None

    @property
    def family(self) -> str:
        """The drive family of its card ("a1000", "v7"); a plan that names no card is read by the rules every
        MECHATROLINK-II card shares and the A1000 family's drive codes (SI-T3 Tables 26/27)."""
        return lookup(self.card).family if self.card else "a1000"

    @property
    def label(self) -> str:
        return self.name or f"{self.address:02X}H"

    def comm_cycle_ns(self, tcycle_ns: int) -> int:
        """Length of this station's communication cycle on a network of *tcycle_ns*."""
        if self.link is Link.ML1:
            return self.com_tim * _MS
        return self.com_tim * tcycle_ns

    def comm_cycles(self, tcycle_ns: int) -> int:
        """Communication cycle in transmission cycles (>= 1)."""
        return max(1, self.comm_cycle_ns(tcycle_ns) // tcycle_ns)


@dataclass(frozen=True, slots=True)
class NetworkPlan:
    """One master, one network generation, one transmission cycle, its stations and the master's policies."""

    link: Link
    """Generation: ML1, ML2 or ML3."""

    tcycle_ns: int
    """Transmission cycle in ns (ML-I 2 ms; ML-II 0.5–8 ms; ML-III 250 us–8 ms)."""

    stations: tuple[StationPlan, ...] = ()
    """The slaves, in service order (addresses unique)."""

    request_timeout_ns: int = 1_000_000_000
    """Default time limit of a request (PRM_RD, CONFIG …) including repeats while CMDRDY is busy."""

    request_retries: int = 3
    """A request whose command goes unanswered this many times in a row fails at once with RequestTimeout (so a
    command the slave never answers cannot make the station look silent until ``request_timeout_ns``)."""

    offline_after: int = 8
    """A station silent for this many consecutive communication cycles becomes OFFLINE."""

    answer_window_ns: int = 0
    """How long a command may still be answered after its station's next slot before it counts as Missing.
    0 (strict): Missing as soon as the next slot comes, as a MECHATROLINK master judges. The host-stall policy
    ``absorb`` (docs/timing.md, "Host stalls") sets it to the stall bound: a slave process that was held up
    answers every command it was sent, late, and none is counted missing (the RTT shows the delay)."""

    clear_attempts: int = 3
    """ALM_CLR + SYNC_SET rounds tried on a communication alarm before falling back to DISCONNECT + CONNECT."""

    connect_backoff: int = 16
    """Communication cycles to wait (sending NOP) after a CONNECT refused with a data-setting error."""

    bringup_window: int = 16
    """At most this many stations in CONNECTING or SYNCING at once; a station in phase 1 that would CONNECT waits,
    and is sent nothing meanwhile (a slave in phase 1 expects no command: it has no watchdog and no reception
    monitor before CONNECT: SI-T3 Table 22 lists no reception failure in phase 1, and SI-ET3 "Communication Phases"
    (Figure 19) says no fault is notified in phase 1). Not a figure of the manuals but the simulator's own pacing:
    CONNECT, SYNC_SET and their answers take the general path at both ends, several times the CPU of the steady
    INV_CTL, and a full line brought up at once can hold the master's clock up for hundreds of milliseconds
    (docs/master.md, "Bring-up window")."""

    spread: bool = True
    """Spread stations with COM_TIM > 1 over the transmission cycles of their communication cycle (station *i*
    of that period is served on cycles ``k`` with ``k % n == i % n``); False serves all on ``k % n == 0``."""

    def __post_init__(self) -> None:
        link = Link(self.link)
        object.__setattr__(self, "link", link)
        object.__setattr__(self, "stations", tuple(self.stations))
        lo, hi = TCYCLE_RANGE_NS[link]
        if not lo <= self.tcycle_ns <= hi:
            raise ValueError(f"transmission cycle {self.tcycle_ns} ns is outside {lo}–{hi} ns on {link.label}")
        if link is Link.ML2 and self.tcycle_ns % (500 * _US):
            raise ValueError(f"MECHATROLINK-II transmission cycles are multiples of 0.5 ms (SI-T3 \"CONNECT\"), "
                             f"got {self.tcycle_ns} ns")
        seen: set[int] = set()
        for st in self.stations:
            if st.link is not link:
                raise ValueError(f"station {st.address:02X}H is {st.link.label} on a {link.label} network")
            if st.address in seen:
                raise ValueError(f"station address {st.address:02X}H appears twice")
            seen.add(st.address)
            if st.link is Link.ML1 and st.comm_cycle_ns(self.tcycle_ns) % self.tcycle_ns:
                raise ValueError(f"station {st.address:02X}H: COM_TIM {st.com_tim} ms is not a whole number of "
                                 f"{self.tcycle_ns} ns transmission cycles")
        if self.offline_after < 2:
            raise ValueError("offline_after must be at least 2 communication cycles")
        if self.bringup_window < 1:
            raise ValueError("bringup_window must be at least 1 station")
        if self.answer_window_ns < 0:
            raise ValueError("answer_window_ns must be >= 0")
        if self.request_retries < 1:
            raise ValueError("request_retries must be at least 1")
        if self.request_timeout_ns <= 0:
            raise ValueError("request_timeout_ns must be positive")

    def station(self, address: int) -> StationPlan:
        for st in self.stations:
            if st.address == address:
                return st
        raise KeyError(f"no station {address:02X}H in the plan")
