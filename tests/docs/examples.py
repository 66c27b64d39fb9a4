"""Every example of README.md and docs/*.md run as a test, with Sybil (https://sybil.readthedocs.io): one test per
fenced block, in the page's order, each page in a working folder and a home of its own (:mod:`tests.docs.shell`).

What each block does, by its language (CONTRIBUTING.md, "Examples in the docs"):

* ``python``: run as a program of its own (a fresh namespace: every name it uses it imports or makes). A block that
  defines a ``test_…`` function is a pytest file: it is written out and run by pytest in a process of its own, as
  a user runs it, and must pass.
* ``console``: each ``$ `` command runs, and what it prints must have the shape of the lines under it
  (:mod:`tests.docs.shapes`: figures and ports are free, ``…`` stands for what the page leaves out).
  ``pytest README.md docs --docs-update`` writes what the commands printed into the page instead.
* ``sh``: each command runs and must exit 0.
* any other language: not run, unless an ``example`` marker gives it a file name.

A marker is an HTML comment on the line before a block's fence, so that a reader of the page does not see it and a
reader of the source does:

* ``<!-- skip: next "needs Docker" -->`` (Sybil's own): the block is not run, and the reason is the test's skip
  reason. For what cannot run here: Docker, swarm, root, another machine, a benchmark.
* ``<!-- example: file=NAME -->``: the block is the file NAME of the page's working folder, for the blocks after it.
* ``<!-- example: sketch -->``: a fragment on purpose (its text says "sketch"): a Python block is compiled and its
  imports run, nothing else.
* ``<!-- example: clock=virtual -->``, ``<!-- example: duration=2s -->``: each ``mlink-sim up`` or ``master`` of the
  block runs with ``--clock virtual`` (unless it has a clock) / ``--duration 2s`` (in place of its own), so that a
  run of seconds or minutes takes a fraction of one. Options combine, separated by blanks.
"""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sybil import Document, Example, Region, Sybil
from sybil.parsers.markdown import SkipParser
from sybil.parsers.markdown.lexers import FencedCodeBlockLexer

from tests.docs import shapes
from tests.docs.shell import REPO, Shell, at_home, commands_of, console_of

__all__ = ["SYBIL", "PAGES", "EDITS", "UPDATE", "STATE", "Page", "apply_edits", "tally", "summary"]

#: ``--docs-update``: console outputs that do not hold are rewritten from what the commands printed;
#: ``--docs-update=figures``: every console output, its figures too
UPDATE = {"on": False, "figures": False}
#: the rewrites of one session: page -> [(start, end, text)]
EDITS: dict[str, list[tuple[int, int, str]]] = {}
STATE = "__docs_page__"  #: the page's state in its Sybil namespace
_MARKER = re.compile(r"<!--\s*example:\s*(?P<options>.*?)\s*-->\s*$")
_OPTIONS = re.compile(r"(?P<key>[a-z]+)(?:=(?P<value>\S+))?")
#: a run of a shipped example that writes nothing and serves nothing: two pages that show it share one run
_CACHEABLE = re.compile(r"mlink-sim up [a-z0-9-]+(?: --no-status| --clock virtual| --seed \d+)*")
_PRINTED: dict[str, list[str]] = {}


@dataclass
class Block:
    """A fenced block as the evaluators read it: its language, its source and where that is in the page, the
    options of its marker."""

    language: str
    source: str
    start: int  #: the source's offset in the page
    options: dict[str, str] = field(default_factory=dict)


@dataclass
class Page:
    """What the blocks of one page share: its temporary folder (its working folder and home in it) and its
    shell."""

    root: Path
    shell: Shell

    @property
    def workdir(self) -> Path:
        return self.shell.workdir


def _options(text: str, fence: int) -> dict[str, str]:
    """The options of an ``example`` marker on the line before the fence at *fence*, if there is one."""
    before = text[:fence].rstrip("\n").rsplit("\n", 1)[-1]
    found = _MARKER.search(before)
    if not found:
        return {}
    out = {}
    for word in found.group("options").split():
        option = _OPTIONS.fullmatch(word)
        if option is None:
            raise ValueError(f"example marker: {word!r} is not an option (tests/docs/examples.py)")
        out[option.group("key")] = option.group("value") or ""
    unknown = set(out) - {"file", "sketch", "clock", "duration"}
    if unknown:
        raise ValueError(f"example marker: unknown option(s) {sorted(unknown)} (tests/docs/examples.py)")
    return out


class BlockParser:
    """The fenced blocks of a page that run (module docstring), each with its evaluator."""

    def __init__(self) -> None:
        self.lexer = FencedCodeBlockLexer(language=r"[\w+-]*")

    def __call__(self, document: Document) -> Iterable[Region]:
        for region in self.lexer(document):
            language = region.lexemes["language"]
            source = region.lexemes["source"]
            options = _options(document.text, region.start)
            evaluator = _EVALUATORS.get(language)
            if "file" in options:
                evaluator = _file
            if evaluator is None:
                continue
            region.parsed = Block(language, str(source), region.start + source.offset, options)
            region.evaluator = evaluator
            yield region


# ------------------------------------------------------------------------------------------------- the page


def _setup(namespace: dict[str, Any]) -> None:
    root = Path(tempfile.mkdtemp(prefix="mlink-docs-"))
    namespace[STATE] = Page(root, Shell(root))


def _teardown(namespace: dict[str, Any]) -> None:
    page: Page = namespace.pop(STATE)
    try:
        bad = page.shell.close()
    finally:
        shutil.rmtree(page.root, ignore_errors=True)
    assert not bad, "\n".join(bad)


def _page(example: Example) -> Page:
    return example.namespace[STATE]


def _edit(example: Example, start: int, end: int, text: str) -> None:
    EDITS.setdefault(example.path, []).append((start, end, text))


def apply_edits() -> list[str]:
    """Write the session's rewrites into their pages; the pages written."""
    for path, edits in EDITS.items():
        text = Path(path).read_text(encoding="utf-8")
        for start, end, new in sorted(edits, reverse=True):
            text = text[:start] + new + text[end:]
        Path(path).write_text(text, encoding="utf-8")
    written = sorted(EDITS)
    EDITS.clear()
    return written


# ------------------------------------------------------------------------------------------------ evaluators


def _file(example: Example) -> None:
    block: Block = example.parsed
    (_page(example).workdir / block.options["file"]).write_text(block.source, encoding="utf-8")


def _is_pytest_file(tree: ast.Module) -> bool:
    return any(isinstance(node, ast.FunctionDef) and node.name.startswith("test_") for node in tree.body)


def _python(example: Example) -> None:
    block: Block = example.parsed
    page = _page(example)
    source = page.shell.to_actual(block.source)
    padded = "\n" * (example.line) + source  # tracebacks name the page's own line numbers
    tree = ast.parse(padded, example.path)
    if "sketch" in block.options:
        imports = [node for node in tree.body if isinstance(node, ast.Import | ast.ImportFrom)]
        with at_home(page.root, page.workdir):
            exec(compile(ast.Module(imports, []), example.path, "exec"), {"__name__": "__main__"})
        return
    if _is_pytest_file(tree):
        _pytest_file(example, page, source)
        return
    with at_home(page.root, page.workdir):
        exec(compile(tree, example.path, "exec"), {"__name__": "__main__"})


def _pytest_file(example: Example, page: Page, source: str) -> None:
    name = f"test_{Path(example.path).stem.replace('-', '_')}_line_{example.line}.py"
    (page.workdir / name).write_text(source, encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", name],
                          cwd=page.workdir, env=page.shell.env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"pytest {name} (the page's line {example.line}) exit {done.returncode}:\n" \
                                 f"{done.stdout}{done.stderr}"


def _adjusted(text: str, options: dict[str, str]) -> str:
    """*text* with the marker's options added to each ``mlink-sim up`` / ``master`` in it."""
    added = {"--clock": options.get("clock"), "--duration": options.get("duration")}

    def add(match: re.Match[str]) -> str:
        command = match.group(1).rstrip()
        if added["--duration"]:  # the marker's duration in place of the command's own
            command = re.sub(r"\s--duration[ =]\S+", "", command)
        extra = [f"{option} {value}" for option, value in added.items() if value and option not in command.split()]
        return " ".join([command, *extra])

    if not any(added.values()):
        return text
    return re.sub(r"(mlink-sim (?:up|master) (?:[^|&;]*?))(?=\s*(?:\||&&|;|$))", add, text)


def _sh(example: Example) -> None:
    block: Block = example.parsed
    shell = _page(example).shell
    for command in commands_of(block.source):
        command.text = _adjusted(command.text, block.options)
        run = shell.run(command)
        if run.status is None:  # a server serving, as in a terminal of its own (tests/docs/shell.py)
            continue
        if command.background or command.until_ctrl_c:
            ok = command.background or run.proc.returncode in (0, 130)
            assert ok, f"{command.text!r} ended with {run.proc.returncode} after Ctrl-C:\n{run.output()}"
            continue
        assert run.proc.returncode == 0, f"{command.text!r} exit {run.proc.returncode}:\n{run.output()}"


def _console(example: Example) -> None:
    block: Block = example.parsed
    shell = _page(example).shell
    failures, rewritten = [], []
    for command in console_of(block.source):
        typed = "\n".join(command.typed)
        command.text = _adjusted(command.text, block.options)
        expected = command.output

        def shown(printed: list[str], expected: list[str] = expected) -> bool:
            return bool(expected) and shapes.holds(shapes.align(expected, [shell.to_page(p) for p in printed]))

        if command.background:  # its lines are its own terminal's; the page shows those of the commands after it
            assert not expected, f"{typed}: a command left running (&) shows no output on the page"
            shell.run(command)
            rewritten.append((typed, []))
            continue
        key = command.text if _CACHEABLE.fullmatch(command.text) else None
        if key in _PRINTED:
            printed = _PRINTED[key]
        else:
            run = shell.run(command, shown=shown)
            printed = [shell.to_page(line) for line in run.lines]
            if key is not None and run.status is not None:
                _PRINTED[key] = printed
        steps = shapes.align(expected, printed)
        if not shapes.holds(steps):
            failures.append(f"{typed}\n{shapes.diff(steps)}")
        rewritten.append((typed, shapes.rewrite(steps, figures=UPDATE["figures"])))
    if (failures and UPDATE["on"]) or UPDATE["figures"]:
        text = "".join(f"{typed}\n" + "".join(f"{line}\n" for line in out) for typed, out in rewritten)
        _edit(example, block.start, block.start + len(block.source), text)
        return
    assert not failures, "what the commands printed does not have the page's shape (- the page, + printed):\n" + \
        "\n".join(failures)


_EVALUATORS = {"python": _python, "console": _console, "sh": _sh}

# ------------------------------------------------------------------------------------------------ the tally

#: what became of the session's examples: test id -> (the block's language, passed | skipped | failed)
OUTCOMES: dict[str, tuple[str, str]] = {}


def tally(nodeid: str, example: Example, outcome: str) -> None:
    """Count one phase's *outcome* of *example* (a marker is not an example); a failure or a skip stands."""
    if isinstance(example.parsed, Block) and OUTCOMES.get(nodeid, ("", "passed"))[1] == "passed":
        OUTCOMES[nodeid] = (example.parsed.language, outcome)


def summary() -> str | None:
    """The session's examples by kind and what ran: ``docs: 105 examples, 82 ran and held, …``."""
    if not OUTCOMES:
        return None
    outcomes = Counter(outcome for _, outcome in OUTCOMES.values())
    kinds = Counter(language for language, _ in OUTCOMES.values())
    ran = Counter(language for language, outcome in OUTCOMES.values() if outcome != "skipped")
    by_kind = ", ".join(f"{language} {n} ({ran[language]} ran)"
                        for language, n in sorted(kinds.items(), key=lambda kv: (-kv[1], kv[0])))
    return (f"docs: {len(OUTCOMES)} examples, {outcomes['passed']} ran and held, {outcomes['failed']} failed, "
            f"{outcomes['skipped']} marked not to run here; by kind: {by_kind}")


#: the pages whose examples run: the README and the manual
PAGES = frozenset([REPO / "README.md", *(REPO / "docs").glob("*.md")])


class _Pages(Sybil):
    def should_parse(self, path: Path) -> bool:
        return path.resolve() in PAGES


SYBIL = _Pages(parsers=[SkipParser(), BlockParser()], path=str(REPO), setup=_setup, teardown=_teardown, name="docs")
