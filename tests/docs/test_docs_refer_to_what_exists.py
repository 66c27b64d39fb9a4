"""README.md, CONTRIBUTING.md, CHANGELOG.md and docs/ refer only to what exists: links, files and folders named in
code spans, ``mlink-sim`` commands and the LICENSE the package declares."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = sorted([REPO / "README.md", REPO / "CONTRIBUTING.md", REPO / "CHANGELOG.md", *(REPO / "docs").glob("*.md")])
#: Top-level folders and files whose paths the docs mention in code spans.
ROOTS = ("configs/", "docs/", "scripts/", "mlink_sim/", "tests/", "benchmarks/")


def _text(doc: Path) -> str:
    return doc.read_text(encoding="utf-8")


def _code(doc: Path) -> list[str]:
    """The lines of fenced blocks and the inline code spans of *doc*."""
    out, in_block = [], False
    for line in _text(doc).splitlines():
        if line.lstrip().startswith("```"):
            in_block = not in_block
            continue
        out += [line] if in_block else re.findall(r"`([^`]+)`", line)
    return out


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_relative_link_points_at_a_file(doc: Path) -> None:
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", _text(doc)):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        path = (doc.parent / target.split("#", 1)[0]).resolve()
        if not path.exists():
            broken.append(target)
    assert not broken, f"{doc.name}: links to nothing: {broken}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_path_in_a_code_span_exists(doc: Path) -> None:
    missing = []
    for span in _code(doc):
        for word in re.split(r"[\s=]+", span):
            word = word.strip("'\",;:(){}")
            if not word.startswith(ROOTS) or any(c in word for c in "*{}<>$[]|…"):
                continue
            path = word.split("::", 1)[0].split("#", 1)[0]
            if not (REPO / path).exists():
                missing.append(word)
    assert not missing, f"{doc.name}: names files that do not exist: {missing}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_mlink_sim_command_in_a_code_span_exists(doc: Path) -> None:
    from mlink_sim.cli import _register_optional, cli

    _register_optional()
    used = set()
    for code in _code(doc):
        used.update(re.findall(r"(?:^|[\s(\[\"])mlink-sim ([a-z][a-z-]*)", code))
    unknown = sorted(used - set(cli.commands))
    assert not unknown, f"{doc.name}: commands that do not exist: {unknown}"


def test_the_declared_licence_has_its_file() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert project["license"] == {"text": "MIT"}
    text = (REPO / "LICENSE").read_text()
    assert text.startswith("MIT License") and "WITHOUT WARRANTY OF ANY KIND" in text


def _headings() -> dict[str, list[str]]:
    return {doc.name: [re.sub(r"^#+\s*", "", line).strip().strip("`").lower()
                       for line in _text(doc).splitlines() if line.startswith("#")]
            for doc in DOCS if doc.parent.name == "docs"}


def test_every_named_section_of_a_page_exists() -> None:
    """A pointer such as ``docs/timing.md, "Host stalls"`` in the code, the benchmarks, the tests or the docs names a
    heading of that page (the start of one, or a part of it), so that a reader who follows it finds the section."""
    headings = _headings()
    sources = [*REPO.glob("mlink_sim/**/*.py"), *REPO.glob("benchmarks/**/*.py"), *REPO.glob("tests/**/*.py"), *DOCS]
    missing = []
    for source in sources:
        text = re.sub(r"\s*\n\s*(#\s*)?", " ", source.read_text(encoding="utf-8"))
        for match in re.finditer(r"(?:docs/)?([a-z-]+\.md),?\s+\"([^\"]{3,80})\"", text):
            page, section = match.group(1), match.group(2).lower().rstrip(".")
            if page in headings and not any(h.startswith(section) or section in h for h in headings[page]):
                missing.append(f"{source.relative_to(REPO)}: {page} \"{match.group(2)}\"")
    assert not missing, "sections that do not exist:\n" + "\n".join(sorted(set(missing)))
