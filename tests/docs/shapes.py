"""An output as the docs show it, held against an output a command printed: by shape, not by figure.

A line's *shape* is the line with its runs of blanks made one space and every figure (a number, with its unit when
one is glued to it: ``135.2us``, ``3s``, ``26.4x``, ``5%``) made ``#``; timestamps and ports are figures too. What
a reader reads stays: the words, the names (``21H``, ``0x21``, ``C1-01``, ``SI-T3``, ``E5``), the fields and their
order. Two more rules come from the docs' own way of cutting an output short:

* a line that is only ``…`` stands for any number of lines (none too);
* a ``…`` inside a line stands for any text.

:func:`align` pairs the lines of a documented output with the lines printed, so that a test can say which lines
differ (:func:`diff`) and the update can write the printed ones in (:func:`rewrite`), keeping every line whose
shape still holds and every ``…`` as the author wrote it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["ELLIPSIS", "shape", "Pattern", "Step", "align", "diff", "rewrite"]

ELLIPSIS = "…"
#: a figure may stand after a blank, an opening bracket or one of these, and before a blank, a closing one or these
_BEFORE = r"(?:(?<=[\s(\[{=/,:;<>±~…])|^)"
_AFTER = r"(?=[\s)\]}=/,:;<>±~…%]|$)"
_UNIT = r"(?:ns|us|µs|ms|s|min|h|x|%|Hz|B|KiB|MiB|kB|MB)?"
_NUMBER = re.compile(_BEFORE + r"[-+]?(?:\d+(?:[.,]\d+)*|\.\d+)(?:[eE][-+]?\d+)?" + _UNIT + _AFTER)
_TIMESTAMP = re.compile(r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d:\d\d(?:\.\d+)?(?:Z|[+-]\d\d:\d\d)?")
_PORT = re.compile(r"(?<=[\w\]]):\d+\b")  #: HOST:PORT, [::1]:PORT
_BLANKS = re.compile(r"\s+")


def shape(line: str) -> str:
    """*line* with its figures as ``#`` and its blanks as one space (module docstring)."""
    line = _TIMESTAMP.sub("#", line)
    line = _PORT.sub(":#", line)
    line = _NUMBER.sub("#", line)
    return _BLANKS.sub(" ", line).strip()


@dataclass(frozen=True)
class Pattern:
    """One line of a documented output: ``…`` alone (any lines), or a line whose shape must match."""

    text: str

    @property
    def any_lines(self) -> bool:
        return self.text.strip() == ELLIPSIS

    def matches(self, line: str) -> bool:
        pieces = [re.escape(shape(piece)) for piece in self.text.split(ELLIPSIS)]
        if len(pieces) == 1:
            return shape(line) == shape(self.text)
        return re.fullmatch(r"\s?.*?\s?".join(pieces), shape(line)) is not None


@dataclass(frozen=True)
class Step:
    """One step of an alignment: ``match`` (a documented line and the printed one it stands for), ``any`` (a
    printed line a ``…`` takes), ``gap`` (a ``…`` that took what it takes), ``missing`` (a documented line nothing
    printed matches) or ``extra`` (a printed line nothing documented stands for)."""

    kind: str
    doc: str | None = None
    printed: str | None = None


def _trim(lines: list[str]) -> list[str]:
    start, end = 0, len(lines)
    while start < end and not lines[start].strip():
        start += 1
    while end > start and not lines[end - 1].strip():
        end -= 1
    return lines[start:end]


def align(documented: list[str], printed: list[str]) -> list[Step]:
    """The alignment of *documented* (the doc's output lines) with *printed* that matches the most lines; it
    holds when it has no ``missing`` and no ``extra`` step. Blank lines at either end do not count."""
    pats = [Pattern(line) for line in _trim(documented)]
    out = _trim(printed)
    n, m = len(pats), len(out)
    # best[i][j]: the score of aligning pats[i:] with out[j:]: the most documented lines matched first (HIT each),
    # then the fewest lines left unmatched (a documented one costs a little more than a printed one)
    hit, miss = 1000.0, 1.001
    best = [[0.0] * (m + 1) for _ in range(n + 1)]
    for i in range(n, -1, -1):
        for j in range(m, -1, -1):
            if i == n:
                best[i][j] = -(m - j)
                continue
            p = pats[i]
            if p.any_lines:
                best[i][j] = max(best[i + 1][j], best[i][j + 1] if j < m else float("-inf"))
                continue
            options = [best[i + 1][j] - miss]
            if j < m:
                options.append(best[i][j + 1] - 1)
                if p.matches(out[j]):
                    options.append(best[i + 1][j + 1] + hit)
            best[i][j] = max(options)
    steps: list[Step] = []
    i = j = 0
    while i < n or j < m:
        if i == n:
            steps.append(Step("extra", printed=out[j]))
            j += 1
            continue
        p = pats[i]
        if p.any_lines:
            if j < m and best[i][j] == best[i][j + 1]:
                steps.append(Step("any", doc=p.text, printed=out[j]))
                j += 1
            else:
                steps.append(Step("gap", doc=p.text))
                i += 1
            continue
        if j < m and p.matches(out[j]) and best[i][j] == best[i + 1][j + 1] + hit:
            steps.append(Step("match", doc=p.text, printed=out[j]))
            i, j = i + 1, j + 1
        elif j < m and best[i][j] == best[i][j + 1] - 1:
            steps.append(Step("extra", printed=out[j]))
            j += 1
        else:
            steps.append(Step("missing", doc=p.text))
            i += 1
    return steps


def holds(steps: list[Step]) -> bool:
    return not any(s.kind in ("missing", "extra") for s in steps)


def diff(steps: list[Step]) -> str:
    """The alignment as a reader checks it: ``  `` a line that holds, ``- `` a documented line nothing printed
    matches, ``+ `` a printed line the doc does not show (``…`` lines as they stand)."""
    out = []
    for s in steps:
        if s.kind == "match":
            out.append(f"  {s.doc}")
        elif s.kind == "gap":
            out.append(f"  {s.doc}")
        elif s.kind == "missing":
            out.append(f"- {s.doc}")
        elif s.kind == "extra":
            out.append(f"+ {s.printed}")
    return "\n".join(out)


def rewrite(steps: list[Step], figures: bool = False) -> list[str]:
    """The documented output made to hold: every line that holds and every ``…`` kept as written (with *figures*,
    a line that holds is written as printed unless it has a ``…`` of its own), a line nothing matches dropped, a
    printed line nothing stands for written in."""
    out: list[str] = []
    for s in steps:
        if s.kind == "match" and figures and ELLIPSIS not in (s.doc or ""):
            assert s.printed is not None
            out.append(s.printed)
        elif s.kind in ("match", "gap"):
            assert s.doc is not None
            out.append(s.doc)
        elif s.kind == "extra":
            assert s.printed is not None
            out.append(s.printed)
    return out
