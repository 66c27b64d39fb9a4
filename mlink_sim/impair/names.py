"""The names of the impairments and faults in force (docs/faults.md, "Names"): one namespace per network or proxy,
so that ``heal NAME`` finds one thing whichever kind it is.

A name is given (``impair 21H 'loss=5%' --name lossy``) or made here from what the thing does and where:
``loss-21H-1``, ``delay-all-2``, ``silence-23H-1`` (the number counts up per what-and-where and is never handed out
twice in a run). A name in force belongs to one kind (``"impairment"`` or ``"fault"``); :meth:`Names.hold` records
it, :meth:`Names.drop` frees it once nothing of that name is left.

Sans-I/O: no clock, no socket.
"""

from __future__ import annotations

import re

__all__ = ["Names", "NAME_RULE", "check_name"]

#: A given name: a letter first, then letters, digits, ``-``, ``_`` or ``.``; at most 40 characters.
NAME_RULE = re.compile(r"[A-Za-z][A-Za-z0-9_.-]{0,39}")
#: Text that reads as a station address (``21H``, ``0x21``, ``33``) or ``all``: never a name, so that ``heal X``
#: means one thing (mlink_sim.units.parse_address reads these forms).
_STATION_LIKE = re.compile(r"(?i)all|0x[0-9a-f]+|[0-9a-f]+h|[0-9]+")


def check_name(name: str) -> str | None:
    """None if *name* can name an impairment or a fault, else why not (one line)."""
    if _STATION_LIKE.fullmatch(name):
        return f"{name!r} reads as a station ('all', 21H, 0x21, 33): a name starts with a letter and is not a station"
    if not NAME_RULE.fullmatch(name):
        return (f"{name!r} is not a name: a letter, then letters, digits, '-', '_' or '.' (at most 40 characters), "
                "e.g. 'lossy-link'")
    return None


class Names:
    """The names in force and the counters the made ones are numbered by."""

    def __init__(self) -> None:
        self._kinds: dict[str, str] = {}  # name -> "impairment" | "fault"
        self._next: dict[str, int] = {}  # "loss-21H" -> the number the next made name gets

    def new(self, what: str, where: str) -> str:
        """A name not in force: ``{what}-{where}-{n}`` (*where*: ``21H`` or ``all``)."""
        stem = f"{what}-{where}"
        n = self._next.get(stem, 1)
        while f"{stem}-{n}" in self._kinds:
            n += 1
        self._next[stem] = n + 1
        return f"{stem}-{n}"

    def kind_of(self, name: str) -> str | None:
        """``"impairment"``, ``"fault"`` or None (no such name in force)."""
        return self._kinds.get(name)

    def hold(self, name: str, kind: str) -> None:
        self._kinds[name] = kind

    def drop(self, name: str) -> None:
        self._kinds.pop(name, None)

    def __contains__(self, name: object) -> bool:
        return name in self._kinds
