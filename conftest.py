"""The examples of README.md and docs/*.md as tests (tests/docs/examples.py; CONTRIBUTING.md, "Examples in the
docs"): ``pytest README.md docs`` runs them, ``--docs-update`` writes what their commands printed into the pages."""

from __future__ import annotations

import pytest

from tests.docs.examples import SYBIL, UPDATE, apply_edits

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
