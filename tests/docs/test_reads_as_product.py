"""The repository reads as the product, not as the record of how it was built: the end states of its documentation
and layout, each checkable with a one-line command (README size, ``ls docs``, a grep for history words, the
``MLINK_`` names, the module sizes)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
DOCS = sorted((REPO / "docs").glob("*.md"))
PACKAGE = REPO / "mlink_sim"

#: Words that narrate history: numbered work rounds and issues, "as before". Case-insensitive.
HISTORY = re.compile(r"sessions? [0-9]|issues? #?[0-9]|as before", re.IGNORECASE)
#: A work round's short tag ("s31"). Lower case only: the manuals' switch and terminal names (S1-2, S2, S3–S7 of
#: the SI-T/V7 and the VS-606V7) are citations of the spec, not history.
ROUND_TAG = re.compile(r"\bs[0-9]{1,2}\b")
#: The environment names the package may read, and where the docs list them.
ENV_TABLE = REPO / "docs" / "configuration.md"
ENV_NAMES = {"MLINK_PURE", "MLINK_BUILD_PURE", "MLINK_SIM_DEBUG", "MLINK_SIM_LOG_LEVEL"}
MAX_MODULE_LINES = 600


def test_the_readme_reads_in_three_minutes() -> None:
    assert README.stat().st_size <= 6000, f"README.md is {README.stat().st_size} bytes, more than 6,000"


def test_the_readme_starts_with_the_install_and_test_commands() -> None:
    block = README.read_text(encoding="utf-8").split("```", 2)[1]
    commands = [line.split()[0] for line in block.splitlines()[1:] if line.strip()]
    assert commands[:2] == ["scripts/up", "scripts/test"]


def test_docs_hold_no_raw_result_files() -> None:
    assert not sorted((REPO / "docs").glob("*.json")), "result files belong in benchmarks/results/"


def test_docs_are_flat_with_an_index() -> None:
    assert (REPO / "docs" / "README.md").is_file()
    index = (REPO / "docs" / "README.md").read_text(encoding="utf-8")
    unlisted = [d.name for d in DOCS if d.name != "README.md" and f"]({d.name})" not in index]
    assert not unlisted, f"pages the index does not list: {unlisted}"
    folders = [p.name for p in (REPO / "docs").iterdir() if p.is_dir() and p.name != "images"]
    assert not folders, f"docs/ is flat (one page per topic; pictures in docs/images/): {folders}"


def test_docs_images_are_pngs_a_page_shows() -> None:
    images = REPO / "docs" / "images"
    if not images.is_dir():
        return
    pages = "".join(d.read_text(encoding="utf-8") for d in DOCS)
    files = sorted(p.name for p in images.iterdir())
    assert all(name.endswith(".png") for name in files), f"docs/images/ holds PNGs only: {files}"
    unshown = [name for name in files if f"](images/{name})" not in pages]
    assert not unshown, f"pictures no page shows: {unshown}"


def test_results_are_named_by_date_and_commit() -> None:
    results = sorted((REPO / "benchmarks" / "results").glob("*.json"))
    assert results
    bad = [p.name for p in results if not re.fullmatch(r"\d{4}-\d{2}-\d{2}-[0-9a-f]{7}-[a-z0-9-]+\.json", p.name)]
    assert not bad, f"not YYYY-MM-DD-<commit7>-<what>.json: {bad}"


def test_performance_is_at_most_40_kb() -> None:
    size = (REPO / "docs" / "performance.md").stat().st_size
    assert size <= 40_000, f"docs/performance.md is {size} bytes"


@pytest.mark.parametrize("doc", [README, *DOCS], ids=lambda p: p.name)
def test_no_history_words(doc: Path) -> None:
    found = [
        f"{n}: {line.strip()[:100]}"
        for n, line in enumerate(doc.read_text(encoding="utf-8").splitlines(), 1)
        if HISTORY.search(line) or ROUND_TAG.search(line)
    ]
    assert not found, f"{doc.name} narrates history:\n" + "\n".join(found)


def _names_in_package() -> set[str]:
    names: set[str] = set()
    for module in PACKAGE.rglob("*.py"):
        names.update(re.findall(r"\bMLINK_[A-Z0-9_]+", module.read_text(encoding="utf-8")))
    return names


def _names_in_the_env_table() -> set[str]:
    text = ENV_TABLE.read_text(encoding="utf-8").split("## Environment", 1)[1]
    return set(re.findall(r"^\| `(MLINK_[A-Z0-9_]+)", text, re.MULTILINE))


def test_at_most_four_environment_names_each_in_the_docs_table() -> None:
    used = _names_in_package()
    assert used <= ENV_NAMES, f"environment names beyond the four: {sorted(used - ENV_NAMES)}"
    assert _names_in_the_env_table() == ENV_NAMES
    tables = [d.name for d in DOCS if re.search(r"^\| `MLINK_PURE", d.read_text(encoding="utf-8"), re.MULTILINE)]
    assert tables == [ENV_TABLE.name], f"one table lists the environment names, not {tables}"


def test_the_readme_names_no_environment_switch_but_mlink_pure() -> None:
    names = set(re.findall(r"\bMLINK_[A-Z0-9_]+", README.read_text(encoding="utf-8")))
    assert names <= {"MLINK_PURE"}, sorted(names)


def test_docs_name_only_environment_names_that_exist() -> None:
    read = _names_in_package() | set(re.findall(r"\bMLINK_[A-Z0-9_]+", (REPO / "Dockerfile").read_text()))
    stale = {
        (doc.name, name)
        for doc in [README, *DOCS]
        for name in re.findall(r"\bMLINK_[A-Z0-9_]+", doc.read_text(encoding="utf-8"))
        if name not in read and name not in ENV_NAMES
    }
    assert not stale, f"names no code reads: {sorted(stale)}"


def test_no_module_over_600_lines() -> None:
    long = {
        str(m.relative_to(REPO)): n
        for m in PACKAGE.rglob("*.py")
        if (n := len(m.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"
