"""The option cards mlink-sim emulates: one :class:`CardProfile` per card, in one table (docs/architecture.md,
"Card profiles").

Every layer that knows cards reads its facts here: the config (the card field, its links, frame sizes and
addresses), the command line (``--card``), the wire's selection tables and the drive's monitors (by
:attr:`CardProfile.selections`), the parameter tables (:attr:`CardProfile.params`), the master (what a card takes
as a sub-command, which drive codes it reports, whether MON1 shows the motor speed), the cards (the station class,
:attr:`CardProfile.station`), the dissector generator and the build (the card modules it compiles). A leaf of the
standard library only, so that the lowest layers and setup.py (which runs without the runtime dependencies) read
it, and ``mlink_sim._accel`` before any compiled module is imported; it names what lives above it by name: links
as ``"ML2"``, a parameter table by its name in :mod:`mlink_sim.params`, the station class as ``"module:Class"``
(resolved by :mod:`mlink_sim.cards.registry` when a card is first created).

A card has one spelling where a user meets it: its :attr:`~CardProfile.key` (``si-t-v7``: the config, ``--card``,
the JSON ``card`` fields) and its :attr:`~CardProfile.label` as its manual names it (``SI-T/V7``: every human
output). :func:`lookup` reads any spelling (``"SI-T/V7"``, ``"si-t/v7"``, ``"sitv7"``: case and punctuation
ignored). A fifth card is one module with its station class and one :func:`register` call (or one record in
:data:`BUILTIN` for a card of the package).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = ["BUILTIN", "LINKS", "CardProfile", "default_for", "lookup", "profiles", "register", "spelling"]

#: The links a card may speak, as :class:`mlink_sim.wire.Link` names them.
LINKS = ("ML1", "ML2", "ML3")
_KEY = re.compile(r"[a-z0-9]+(?:-[a-z0-9]+)*")
_STATION = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")


@dataclass(frozen=True, eq=False)
class CardProfile:
    """One option card: what every layer needs to know of it without importing its station class.

    The facts of the manual carry their citation in :attr:`sources` (by field name); a behaviour flag is named
    for the behaviour, so that a layer asks "does this card take PRM_RD as a sub-command only?", never "is it the
    SI-T/V7?"."""

    key: str  #: ``si-t-v7``: the config's ``card``, ``--card``, the JSON ``card`` fields, the EEPROM image's card
    label: str  #: ``SI-T/V7``: as its manual names it; every human output
    manual: str  #: the manual's title as /work/shared/manuals names its file (``/`` for the file name's ``-``)
    station: str  #: the station class, ``"module:Class"`` (:mod:`mlink_sim.cards.registry` imports it when needed)
    family: str  #: the drive family: :class:`mlink_sim.drive.Family` value, key of :data:`mlink_sim.params.FAMILIES`
    params: str  #: its parameter table's name in :mod:`mlink_sim.params` (``A1000_SI_T3``)
    frames: Mapping[str, tuple[int, ...]]  #: link -> its frame sizes, the default first; the first link is the default
    addresses: tuple[int, int]  #: the valid station addresses, lowest and highest (``sources["addresses"]``)
    selections: str  #: the key of its SEL_MON / SEL_REF tables in :mod:`mlink_sim.wire.selections`
    max_frequency: str  #: the maximum output frequency parameter (E1-04 / n011): speeds are checked against it
    frequency_units: str  #: the frequency reference units parameter (o1-03 / n035)
    motor_speed: str | None = None  #: the monitor of the motor speed in its SEL_MON table (U1-05), None: it has none
    #: the links on which a station whose card is not known is taken to be this card (one card per link)
    assumed_on: tuple[str, ...] = ()
    #: with sub-commands in the frame (32-byte), PRM_RD/PRM_WR are taken only as sub-commands: the master sends
    #: them there, and a 32-byte station of this card has sub-commands on by default
    prm_as_subcommand: bool = False
    #: CONFIG is a sub-command too: its combination table is SI-T3 Table 7 with a CONFIG column
    #: (:data:`mlink_sim.wire.combinations.V7_COMBINATIONS`)
    config_subcommand: bool = False
    #: the STATUS field has bits E (SEL_M) and F (ZERO_SERVO) (SI-T3 "STATUS Field")
    status_bits_e_f: bool = True
    #: address, frame size and link speed are set by switches (a DIP switch and a rotary switch), not by the
    #: F6-20/F6-21/F6-22 parameters
    set_by_switches: bool = False
    #: field name -> where the manual says it: "frames", "addresses", "motor_speed" and each behaviour flag set;
    #: "frames ML1" (a link's name) where a link carries fewer sizes than the others
    sources: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "frames", MappingProxyType({k: tuple(v) for k, v in self.frames.items()}))
        object.__setattr__(self, "sources", MappingProxyType(dict(self.sources)))
        object.__setattr__(self, "assumed_on", tuple(self.assumed_on))
        where = f"card profile {self.key!r}"
        if not _KEY.fullmatch(self.key):
            raise ValueError(f"{where}: the key is lower-case words joined by '-', e.g. 'si-t3'")
        if not self.label.strip():
            raise ValueError(f"{where}: the label is empty")
        if not _STATION.fullmatch(self.station):
            raise ValueError(f"{where}: station {self.station!r} is not 'module:Class'")
        if not self.frames:
            raise ValueError(f"{where}: it speaks no link")
        for link, sizes in self.frames.items():
            if link not in LINKS or not sizes:
                raise ValueError(f"{where}: frames {link!r}: {sizes!r} (links {', '.join(LINKS)}, each with sizes)")
        for link in self.assumed_on:
            if link not in self.frames:
                raise ValueError(f"{where}: assumed on {link}, a link it does not speak")
        lo, hi = self.addresses
        if not 0 <= lo <= hi <= 0xFF:
            raise ValueError(f"{where}: addresses {lo:02X}H–{hi:02X}H are not a range of one byte")

    @property
    def links(self) -> tuple[str, ...]:
        """The links it speaks, the default first."""
        return tuple(self.frames)

    @property
    def default_link(self) -> str:
        return next(iter(self.frames))

    @property
    def module(self) -> str:
        """The module of its station class (``mlink_sim.cards.si_t3``)."""
        return self.station.partition(":")[0]

    def __repr__(self) -> str:
        return f"CardProfile({self.key!r}, {self.label!r})"


#: The cards of the package, each as its manual describes it.
BUILTIN: tuple[CardProfile, ...] = (
    CardProfile(
        key="si-t3", label="SI-T3", manual="SI-T3 MECHATROLINK-II technical manual",
        station="mlink_sim.cards.si_t3:SiT3", family="a1000", params="A1000_SI_T3",
        frames={"ML2": (32, 17), "ML1": (17,)}, addresses=(0x21, 0x3E), selections="SI-T3",
        max_frequency="E1-04", frequency_units="o1-03", motor_speed="U1-05",
        sources={
            "frames": "SI-T3 Table 4 F6-21 (0 = 32-byte) and F6-22 (0 = 10 Mbps MECHATROLINK-II), the defaults; "
                      "MECHATROLINK-I carries 17-byte frames only (SI-T3 Table 29 note <3>)",
            "frames ML1": "SI-T3 Table 29 note <3>",
            "addresses": "SI-T3 Table 4 F6-20: 21H–3EH (20H and 3FH raise AEr)",
            "motor_speed": "SI-T3 Table 18: SEL_MON 1 is U1-05 motor speed",
        },
    ),
    CardProfile(
        key="si-et3", label="SI-ET3", manual="SI-ET3 MECHATROLINK-III technical manual",
        station="mlink_sim.cards.si_et3:SiEt3", family="a1000", params="A1000_SI_ET3",
        frames={"ML3": (64, 32)}, addresses=(0x03, 0xEF), selections="SI-ET3",
        max_frequency="E1-04", frequency_units="o1-03", motor_speed="U1-05", assumed_on=("ML3",),
        sources={
            "frames": "SI-ET3 Table 7 F6-21 (0 = 64-byte, the default); Table 28",
            "addresses": "SI-ET3 Table 7 F6-20: 03H–EFH",
            "motor_speed": "SI-ET3 Table 22: SEL_MON 1 is U1-05 motor speed",
        },
    ),
    CardProfile(
        key="si-t-v7", label="SI-T/V7", manual="SI-T/V7 MECHATROLINK-I/II technical manual",
        station="mlink_sim.cards.si_t_v7:SiTV7", family="v7", params="VS606V7",
        frames={"ML2": (32, 17), "ML1": (17,)}, addresses=(0x21, 0x3E), selections="SI-T/V7",
        max_frequency="n011", frequency_units="n035", motor_speed=None, assumed_on=("ML1",),
        prm_as_subcommand=True, config_subcommand=True, status_bits_e_f=False, set_by_switches=True,
        sources={
            "frames": "V7 §3.4 S1-1 (ON = 10 Mbps MECHATROLINK-II) and S1-2 (ON = 32-byte), the factory settings; "
                      "MECHATROLINK-I carries 17-byte frames only (S1-1 note)",
            "frames ML1": "V7 §3.4 S1-1 note",
            "addresses": "V7 §3.4 S1-3 and S2: 21H–3EH (20H and 3FH raise AEr)",
            "motor_speed": "V7 Table 5: SEL_MON 1 is the output frequency U-02; no code selects the motor speed",
            "prm_as_subcommand": "V7 §7.1, PRM_RD: \"can be used only in a sub-command\"",
            "config_subcommand": "V7 §7.2: CONFIG as a sub-command",
            "status_bits_e_f": "V7 §7.3 \"STATUS Field\": bits E and F are not used",
            "set_by_switches": "V7 §3.4: DIP switch S1 (link speed, frame size, tens digit) and rotary switch S2",
        },
    ),
)

_PROFILES: dict[str, CardProfile] = {}  # key -> profile, in registration order
_SPELLINGS: dict[str, CardProfile] = {}  # normalised key and label -> profile
_ASSUMED: dict[str, CardProfile] = {}  # link -> the card a station of unknown card on it is taken to be


def spelling(name: str) -> str:
    """A card's name as :func:`lookup` compares it, without case and punctuation: "SI-T/V7", "si-t-v7" and "sitv7"
    are ``"sitv7"`` (the dissector reads its preference the same way)."""
    return "".join(ch for ch in name.lower() if ch.isalnum())


def register(profile: CardProfile) -> CardProfile:
    """Add *profile* to the cards every layer knows (a fifth card: docs/architecture.md, "Card profiles"). A key
    or label another card already has (in any spelling), or a link another card is assumed on: ValueError."""
    for name in (profile.key, profile.label):
        other = _SPELLINGS.get(spelling(name))
        if other is not None:
            raise ValueError(f"card {profile.key!r}: {name!r} is already the card {other.key!r} ({other.label})")
    for link in profile.assumed_on:
        if link in _ASSUMED:
            raise ValueError(f"card {profile.key!r}: a station of unknown card on {link} is already taken to be "
                             f"{_ASSUMED[link].label}")
    _PROFILES[profile.key] = profile
    for name in (profile.key, profile.label):
        _SPELLINGS[spelling(name)] = profile
    for link in profile.assumed_on:
        _ASSUMED[link] = profile
    return profile


def profiles() -> tuple[CardProfile, ...]:
    """Every registered card, the built-in ones first."""
    return tuple(_PROFILES.values())


def lookup(name: str) -> CardProfile:
    """The card *name* names in any spelling: its key or label, any case or punctuation (``"SI-T/V7"``,
    ``"si-t/v7"``, ``"sitv7"``). An unknown name: ValueError listing the cards."""
    profile = _SPELLINGS.get(spelling(name)) if isinstance(name, str) else None
    if profile is None:
        raise ValueError(f"unknown option card {name!r} (known cards: {', '.join(_PROFILES)})")
    return profile


def default_for(link: object) -> CardProfile | None:
    """The card a station of unknown card on *link* (``"ML3"`` or a :class:`~mlink_sim.wire.Link`) is taken to be
    where a card's tables are needed (parameter names): the SI-ET3 on MECHATROLINK-III, the SI-T/V7 on
    MECHATROLINK-I (:attr:`CardProfile.assumed_on`); None where no card is (MECHATROLINK-II: SI-T3 or SI-T/V7)."""
    return _ASSUMED.get(str(getattr(link, "name", link)))


for _profile in BUILTIN:
    register(_profile)
del _profile
