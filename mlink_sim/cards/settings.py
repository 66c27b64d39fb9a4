"""Power-up settings of a card and the documented alternatives (card options).

The manuals read the station address, frame size and link speed once, at power-up ("Power must be cycled
in order for any setting changes to take affect", SI-T3 Table 4 <3>; SI-ET3 Table 7 <9>): F6-20/F6-21/F6-22
on SI-T3 and SI-ET3, DIP switch S1 and rotary switch S2 on the SI-T/V7 (V7 §3.4). A station therefore gets
them in :class:`CardSettings` when it is created (= the slave process starts).

:func:`settings_for` turns the slave command line (``--station 0x21 --frame-size 32 --param C1-01=5.0``)
into :class:`CardSettings` for a card, with one-sentence errors for impossible input. A station address the
card rejects at power-up (SI-T3 / SI-T/V7 20H and 3FH) is *not* an error here: the card powers up with the
AEr minor fault and does not answer, as the manuals describe (docs/cards.md).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from mlink_sim.params import ParamError, for_card
from mlink_sim.profiles import CardProfile, lookup
from mlink_sim.wire import Link

__all__ = ["CardOptions", "CardSettings", "settings_for"]


@dataclass(frozen=True)
class CardOptions:
    """Documented alternatives where the manuals disagree (docs/cards.md, "Card options")."""

    #: SI-ET3: read COM_MOD SYNCMODE per SI-ET3 Table 19 (0 = synchronous) instead of the MECHATROLINK-II
    #: convention (1 = synchronous, phase 3), which is the default.
    et3_syncmode_table19: bool = False
    #: SI-ET3: accept NOP in phase 1 as the NOP section says ("The command can be used in all communication
    #: phases"; CMD_ALM 0, CMDRDY 1) – the default; False reads Table 9 / Table 10 ("–": CMD_ALM / SUBCMD_ALM CH).
    et3_nop_in_phase1: bool = True
    #: SI-ET3: place the CONNECT response echo at bytes 5–8 as the printed response table shows, instead of
    #: at the command's bytes 4–7.
    et3_connect_echo_at_byte5: bool = False
    #: SI-ET3: also raise AEr for F6-20 = 20H / 3FH (SI-ET3 Table 7 note <10>, copied from SI-T3).
    et3_aer_on_20_3f: bool = False
    #: SI-T/V7: accept PRM_RD/PRM_WR as main commands in 32-byte mode (as SI-T3 Table 7 does) instead of A.95.
    v7_prm_main_in_32byte: bool = False
    #: MECHATROLINK-I CONNECT: accept EXMOD = 1 (expanded connection, forced asynchronous) instead of A.94.
    ml1_exmod_accepted: bool = False
    #: Reception-failure timer tolerance in ns beyond one communication cycle; None = max(cycle, 2 ms).
    silence_tolerance_ns: int | None = None


@dataclass(frozen=True)
class CardSettings:
    """What a card reads at power-up (plus the simulated drive's load and the card options)."""

    #: Raw parameter values by name, applied over the family defaults and the EEPROM image (F6-20 station
    #: address, F6-21 frame size, F6-22 link speed on SI-T3/SI-ET3; n-number constants such as n003 on the SI-T/V7).
    params: Mapping[str, int] = field(default_factory=dict)
    #: SI-T/V7 DIP switch S1-1: True = 10 Mbps (MECHATROLINK-II, factory setting), False = 4 Mbps (MECHATROLINK-I).
    s1_1_10mbps: bool = True
    #: SI-T/V7 DIP switch S1-2: True = 32-byte data transmission (factory setting), False = 17-byte.
    s1_2_32byte: bool = True
    #: SI-T/V7 station number, set by S1-3 (tens digit 2/3) and rotary switch S2 (ones digit); None = 21H.
    station: int | None = None
    #: Mechanical load of the simulated drive (``mlink_sim.drive.LoadSpec``); None = a load scaled to the motor.
    load: Any = None
    #: Documented alternatives (:class:`CardOptions`).
    options: CardOptions = field(default_factory=CardOptions)

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))

    def __hash__(self) -> int:
        return hash((tuple(sorted(self.params.items())), self.s1_1_10mbps, self.s1_2_32byte, self.station,
                     self.options))

    @property
    def s1_3(self) -> bool:
        """SI-T/V7 S1-3: ON = tens digit 3 (V7 §3.4 "Station-number Setting")."""
        return ((self.station if self.station is not None else 0x21) >> 4) == 3

    @property
    def s2(self) -> int:
        """SI-T/V7 rotary switch S2: the ones digit of the station number."""
        return (self.station if self.station is not None else 0x21) & 0xF


def _sizes(sizes: tuple[int, ...]) -> str:
    return " or ".join(map(str, sizes))


def _only(profile: CardProfile, link: Link) -> str:
    """"MECHATROLINK-I (4 Mbps) carries 17-byte frames only (SI-T3 Table 29 note <3>)"."""
    source = profile.sources.get(f"frames {link.name}")
    return (f"{link.label} ({link.speed_mbps} Mbps) carries {_sizes(profile.frames[link.name])}-byte frames only"
            + (f" ({source})" if source else ""))


def settings_for(
    card: str,
    station: int,
    frame_size: int | None,
    param_assignments: Iterable[str],
    load: Any = None,
    *,
    link_speed_mbps: int | None = None,
    options: CardOptions | None = None,
) -> CardSettings:
    """:class:`CardSettings` for *card* (any spelling of a registered card) from the slave command line, by what its
    profile says (:mod:`mlink_sim.profiles`: its links and frame sizes, whether switches set them).

    *station*: SI-T3 F6-20 (20H–3FH), SI-ET3 F6-20 (03H–EFH), SI-T/V7 switches S1-3/S2 (20H–3FH); 20H/3FH
    are accepted and make SI-T3/SI-T/V7 power up with AEr. *frame_size*: 17/32 (SI-T3, SI-T/V7) or 32/64
    (SI-ET3); None keeps F6-21 / the S1-2 factory setting. *param_assignments*: ``"C1-01=5.0"``,
    ``"0x0200=50"``. *link_speed_mbps*: 10 or 4 (MECHATROLINK-II / -I; SI-T3 F6-22, SI-T/V7 S1-1).
    Raises :class:`ValueError` (or its subclass :class:`~mlink_sim.params.ParamError`) with a one-sentence
    message.
    """
    profile = lookup(card)
    label = profile.label
    table = for_card(profile)
    params: dict[str, int] = {}
    for text in param_assignments:
        p, raw = table.parse_assignment(text)
        params[p.name] = raw
    opts = options if options is not None else CardOptions()
    if isinstance(station, bool) or not isinstance(station, int):
        raise ValueError(f"{label}: the station address must be a whole number, not {station!r}")
    links = [Link[name] for name in profile.links]  # the default first: F6-22 = 0 / S1-1 ON
    speeds = {link.speed_mbps: link for link in links}
    default_sizes = profile.frames[profile.default_link]  # the default first: F6-21 = 0 / S1-2 ON
    if link_speed_mbps is not None and link_speed_mbps not in speeds:
        allowed = " or ".join(f"{mbps}" for mbps in speeds)
        setting = "S1-1: " if profile.set_by_switches else "F6-22: " if len(speeds) > 1 else ""
        raise ValueError(f"{label}: link speed {link_speed_mbps} Mbps is not possible ({setting}{allowed} Mbps"
                         f"{'' if len(speeds) > 1 else ' only'})")
    link = links[0] if link_speed_mbps is None else speeds[link_speed_mbps]

    if profile.set_by_switches:  # V7 §3.4: S1-1 link speed, S1-2 frame size, S1-3 + S2 the station number
        lo, hi = profile.addresses
        if not lo & 0xF0 <= station <= hi | 0x0F:  # the tens digits of the valid range, any ones digit (S2)
            raise ValueError(f"{label}: station {station:02X}H cannot be set with S1-3 and S2 "
                             f"({lo & 0xF0:02X}H–{hi | 0x0F:02X}H; {lo:02X}H–{hi:02X}H are valid)")
        every = tuple(sorted({size for sizes in profile.frames.values() for size in sizes}))
        if frame_size not in (None, *every):
            raise ValueError(f"{label}: frame size {frame_size} is not possible (S1-2 selects {_sizes(every)} bytes)")
        sizes = profile.frames[link.name]
        if frame_size is not None and frame_size not in sizes:
            raise ValueError(f"{label}: {_only(profile, link)}")
        size = sizes[0] if frame_size is None and link is not links[0] else frame_size or default_sizes[0]
        return CardSettings(params, s1_1_10mbps=link is links[0], s1_2_32byte=size == default_sizes[0],
                            station=station, load=load, options=opts)

    f6_20 = table.by_name("F6-20")
    if not f6_20.minimum <= station <= f6_20.maximum:
        raise ParamError(
            f"{label}: station {station:02X}H is outside the F6-20 range "
            f"{f6_20.minimum:02X}H–{f6_20.maximum:02X}H"
        )
    params["F6-20"] = station
    if frame_size is not None:
        if frame_size not in default_sizes:
            raise ValueError(f"{label}: frame size {frame_size} is not possible (F6-21 selects "
                             f"{_sizes(tuple(sorted(default_sizes)))} bytes)")
        params["F6-21"] = default_sizes.index(frame_size)
    if len(links) > 1:  # F6-22 selects the link
        if link_speed_mbps is not None:
            params["F6-22"] = links.index(link)
        f6_21 = params.get("F6-21", table.by_name("F6-21").default)
        f6_22 = params.get("F6-22", table.by_name("F6-22").default)
        link, size = links[f6_22], default_sizes[f6_21]
        if size not in profile.frames[link.name]:
            raise ValueError(f"{label}: with F6-22 = {f6_22}, {_only(profile, link)}; use --frame-size "
                             f"{profile.frames[link.name][0]}")
    return CardSettings(params, load=load, options=opts)
