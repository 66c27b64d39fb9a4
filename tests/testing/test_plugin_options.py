"""The pytest plugin's configuration errors and report files, run in a pytester sandbox."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

QUICKSTART = Path(__file__).resolve().parents[2] / "configs" / "quickstart.toml"


@pytest.fixture(autouse=True)
def _ini(pytester):
    pytester.makeini("[pytest]\nasyncio_default_fixture_loop_scope = function\n")


def test_fixture_without_a_config_is_a_usage_error(pytester):
    pytester.makepyfile("def test_x(mlink_network):\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.stdout.fnmatch_lines(["*mlink_network needs a config*--mlink-config*"])
    assert result.ret != 0


def test_marker_is_registered(pytester):
    result = pytester.runpytest("--markers")
    result.stdout.fnmatch_lines(["*mlink_network(config*"])


@pytest.mark.e2e
def test_report_dir_gets_one_report_per_network(pytester, tmp_path):
    pytester.makepyfile(f"""
        import pytest

        @pytest.mark.mlink_network({str(QUICKSTART)!r})
        def test_up(mlink_network):
            mlink_network.wait(0.3)
            assert mlink_network.metrics.cycles > 0
    """)
    reports = tmp_path / "reports"
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", f"--mlink-report-dir={reports}")
    result.assert_outcomes(passed=1)
    (path,) = reports.glob("*.json")
    report = json.loads(path.read_text())
    assert report["meta"]["network"] == "quickstart" and report["cycles"] > 0


def test_virtual_clock_marker_and_a_bad_clock(pytester, tmp_path):
    pytester.makepyfile(f"""
        import pytest

        @pytest.mark.mlink_network({str(QUICKSTART)!r}, clock="virtual", seed=2)
        def test_virtual(mlink_network):
            mlink_network.wait(0.5)
            assert mlink_network.now > 0.5 and mlink_network.metrics.cycles >= 249

        @pytest.mark.mlink_network({str(QUICKSTART)!r}, clock="sundial")
        def test_bad_clock(mlink_network):
            pass
    """)
    reports = tmp_path / "reports"
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", f"--mlink-report-dir={reports}")
    result.assert_outcomes(passed=1, errors=1)
    result.stdout.fnmatch_lines(["*clock must be 'real' or 'virtual', got 'sundial'*"])
    (path,) = reports.glob("*virtual*.json")
    report = json.loads(path.read_text())
    assert report["meta"]["clock"] == "virtual" and report["meta"]["seed"] == 2
