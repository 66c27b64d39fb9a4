"""scripts/test's own arguments: ``--repeat N`` takes a count of runs, and a wrong one is a usage error before
anything is installed or run (docs/ci.md, "A suite that never flakes")."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "test"


@pytest.mark.parametrize("argv", [["--repeat"], ["--repeat", "0"], ["--repeat", "five"], ["--repeat", "-1"]])
def test_a_repeat_without_a_count_of_runs_is_a_usage_error(argv: list[str]) -> None:
    r = subprocess.run(["bash", str(SCRIPT), *argv], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and "--repeat needs a count of runs" in r.stderr, r.stderr
