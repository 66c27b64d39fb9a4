"""The code's docstrings and comments say what holds and why, never a day's measurement or how the code got there:
the package, setup.py, scripts/ and benchmarks/ carry no lab notes ("on this VM", "3 of 6 runs", "64–121 ms
here", "≈ 4 min on a 2-vCPU VM", a dated figure) and no history words. A measurement lives in docs/performance.md,
with its date, commit and machine; the code points there. The scanner is checked on sample sentences below."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

#: A day's measurement in prose (case-insensitive): the machine it was taken on, a count of runs, a figure "here",
#: an approximate figure with its unit (a cost; "~25 min" for a benchmark's own run is its durations' sum), a date.
LAB_NOTE = re.compile(
    r"\bthis (?:vm|machine|box|laptop)\b"
    r"|\b\d+[- ]vcpus?\b"
    r"|\b\d+ of \d+ (?:runs?|tries|trials|attempts|failed|held|passed)\b"
    r"|\bwith \d+, \d+ of \d+\b"
    r"|\d(?:\s?(?:ns|µs|us|ms|s|min|%))\b[^.;:\n]{0,24}\bhere\b"
    r"|\bhere\b[^.;:\n]{0,12}\d[\d.,]*\s?(?:ns|µs|us|ms|%)"
    r"|\bmeasured (?:here|on (?:an?|the|this|\d)|with)\b|\(measured\b"
    r"|\btook \d[\d.,–-]*\s?(?:ns|µs|us|ms|s|min)\b"
    r"|≈\s?\d[\d.,]*\s?(?:ns|µs|us|ms|s|min|%)(?!\w)|~\s?\d[\d.,]*\s?(?:ns|µs|us|ms|%)(?!\w)"
    r"|\b(?:the|our) (?:bench|test|build) (?:machine|box|vm)\b"
    r"|\b20\d\d-\d\d-\d\d\b(?!-[0-9a-f]{7})",
    re.IGNORECASE,
)
#: Words that narrate how the code got there (the docs' list, tests/docs/test_reads_as_product.py, and more). Not
#: "now" or "no longer": in code they say what happens at run time ("the previous command is no longer the
#: outstanding one").
HISTORY = re.compile(
    r"\bsessions? [0-9]|\bissues? #?[0-9]|\bas before\b|\bpreviously\b|\bformerly\b|\brefactor"
    r"|\bused to be\b|\bwork rounds?\b",
    re.IGNORECASE,
)


def prose_of(source: str) -> list[tuple[int, str]]:
    """The docstrings and comments of Python *source*, ``(line, text)`` each."""
    out: list[tuple[int, str]] = []
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            out.append((tok.start[0], tok.string))
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        for stmt in body:  # a docstring, or a string standing as a statement (an attribute's note)
            if (isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant)
                    and isinstance(stmt.value.value, str)):
                out.append((stmt.lineno, stmt.value.value))
    return out


def shell_comments(source: str) -> list[tuple[int, str]]:
    """The comments of a shell script (its ``#`` lines and line ends; not the ``#!`` line)."""
    out = []
    for n, line in enumerate(source.splitlines(), 1):
        if n == 1 and line.startswith("#!"):
            continue
        at = line.find("#")
        if at >= 0 and (at == 0 or line[at - 1] in " \t") and not line[at:].startswith("#{"):
            out.append((n, line[at:]))
    return out


def findings(text: str) -> list[str]:
    """What in *text* reads as a lab note or as history (the matched words)."""
    flat = " ".join(text.split())  # a sentence broken over lines is read as one
    return [m.group(0) for pattern in (LAB_NOTE, HISTORY) for m in pattern.finditer(flat)]


def _files() -> list[Path]:
    files = [*sorted((REPO / "mlink_sim").rglob("*.py")), REPO / "setup.py",
             *sorted(p for p in (REPO / "benchmarks").rglob("*.py")),
             *sorted(p for p in (REPO / "scripts").iterdir() if p.is_file())]
    return [p for p in files if "results" not in p.relative_to(REPO).parts]


@pytest.mark.parametrize("path", _files(), ids=lambda p: str(p.relative_to(REPO)))
def test_docstrings_and_comments_say_what_holds(path: Path) -> None:
    source = path.read_text(encoding="utf-8")
    is_python = path.suffix == ".py" or source.startswith("#!/usr/bin/env python")
    prose = prose_of(source) if is_python else shell_comments(source)
    found = [f"{path.relative_to(REPO)}:{n}: {hit!r} in {' '.join(text.split())[:110]!r}"
             for n, text in prose for hit in findings(text)]
    assert not found, ("a lab note or history in the code (measurements go to docs/performance.md, history to "
                       "CHANGELOG.md):\n" + "\n".join(found))


#: Sentences the code carried, each a lab note the scan must find.
LAB_NOTES = [
    "A worker on a busy machine became lost commands in the quickstart (3 of 6 runs failed; with 8, 0 of 6).",
    "the query answers on a loaded host too (62 stations paced took 64–121 ms here)",
    "it cost the 8-station 250 µs line here ≈ 30 µs per hop and, at times, whole cycles",
    "on this VM the round trip of 62 ML-III stations rose from 252–291 to 311–332 µs (p50)",
    "Measured on a 2-vCPU machine, a yield costs under a microsecond.",
    "1.8–3.1 µs per block on the project's 2-vCPU VM",
    "would compile the cores again (≈ 4 min on a 2-vCPU VM)",
    "argtypes' conversions cost ~1.5 µs per call (measured here).",
    "On this 2-vCPU machine the kernel's path costs about 10 µs of CPU per datagram",
    "a full collection took 28–56 ms on 2026-11-30",
    "a read cut by slicing costs 14 µs for 62 datagrams on the bench machine",
    "its first call reads the interpreter binary (~17 ms)",
    "pauses of up to 4.2 ms in a 15 s window (measured with ``gc.callbacks``)",
    "The figures were previously read twice; the refactor reads them once.",
]
#: Sentences that state what holds (design bounds, pointers, the running machine): the scan leaves them.
HOLDS = [
    "A worker yields between two empty reads because the master may share its CPU.",
    "The per-datagram calls cost a system call each (docs/performance.md, 'Batched calls').",
    "bits 0-3 of the WDT echo the slave's count; a burst of 62 answers goes as one packet",
    "Strategies the kernel offers where the process runs; the floor is measured in the same run.",
    "The lead is the timer's late wake-up plus 30 µs, at most the poll's length.",
    "results/2026-12-04-34170df-capacity.json holds the raw figures",
]


@pytest.mark.parametrize("sentence", LAB_NOTES)
def test_the_scan_finds_a_lab_note(sentence: str) -> None:
    assert findings(sentence), sentence


@pytest.mark.parametrize("sentence", HOLDS)
def test_the_scan_leaves_what_holds(sentence: str) -> None:
    assert not findings(sentence), findings(sentence)


def test_the_scan_reads_comments_docstrings_and_attribute_notes() -> None:
    source = '"""Module: fine."""\nX = 1  # 64–121 ms here\n\n\ndef f():\n    """On this VM it waits."""\n'
    assert [n for n, text in prose_of(source) if findings(text)] == [2, 6]
    assert shell_comments("#!/bin/sh\necho hi  # took 3 of 6 runs; fine\n") == [(2, "# took 3 of 6 runs; fine")]
