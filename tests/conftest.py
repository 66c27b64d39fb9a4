"""What every test starts from: the library's logging as the package leaves it (quiet, through the standard
library's ``logging``), whatever an earlier test did. A command run in the test's own process (click's CliRunner,
a ``main()``) configures structlog for the whole process, as the command line does; without this the next test's
log checks would read structlog's output instead of ``caplog``'s."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import structlog


@pytest.fixture(autouse=True)
def _library_logging() -> Iterator[None]:
    yield
    if structlog.is_configured():
        structlog.reset_defaults()
