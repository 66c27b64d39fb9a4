"""The examples of README.md and docs/*.md as tests (tests/docs/examples.py; CONTRIBUTING.md, "Examples in the
docs"): ``pytest README.md docs`` runs them, ``--docs-update`` writes what their commands printed into the pages."""

from __future__ import annotations

from collections.abc import Generator

import pytest
from sybil.integration.pytest import SybilItem

from tests.docs.examples import SYBIL, UPDATE, apply_edits, summary, tally

pytest_collect_file = SYBIL.pytest()


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--docs-update", nargs="?", const="shapes", default=None, choices=("shapes", "figures"),
                     help="write what the docs' console commands printed into the pages: where it does not have "
                          "their shape, or (=figures) every line, its figures too (CONTRIBUTING.md, 'Examples in "
                          "the docs')")


def pytest_configure(config: pytest.Config) -> None:
    mode = config.getoption("--docs-update")
    UPDATE["on"] = mode is not None
    UPDATE["figures"] = mode == "figures"


def pytest_sessionfinish(session: pytest.Session) -> None:
    for page in apply_edits():
        print(f"\ndocs: rewrote the outputs of {page}")


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, pytest.TestReport,
                                                                                           pytest.TestReport]:
    report = yield
    if isinstance(item, SybilItem) and (report.when == "call" or not report.passed):
        tally(item.nodeid, item.example, report.outcome)
    return report


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    line = summary()
    if line is not None:
        terminalreporter.write_line(line)
