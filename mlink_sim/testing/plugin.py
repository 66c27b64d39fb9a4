"""The pytest plugin (entry point ``pytest11``): fixtures that bring a network up for the duration of a test.

    @pytest.mark.mlink_network("configs/quickstart.toml")
    def test_latency(mlink_network):
        mlink_network.run(0x21, hz=30)
        mlink_network.wait(2.0)
        assert mlink_network.metrics.rtt.p99 < 0.5e-3

Fixtures:

- ``mlink_network`` — a started :class:`~mlink_sim.testing.RunningNetwork`. Its config comes from the test's
  ``mlink_network`` marker (``@pytest.mark.mlink_network(CONFIG, workers=…, timeline=…, bringup_timeout=…)``),
  else ``--mlink-config`` / the ``mlink_config`` ini option. Stopped after the test. With ``clock="virtual"``
  (and ``seed=N``) it is a :class:`~mlink_sim.testing.virtual.VirtualRunningNetwork`: the same methods, the
  network in the test's process on simulated time (``wait(2.0)`` returns at once; docs/virtual-time.md).
  On either clock ``mlink_network.impair(0x21, loss=0.1, for_=2.0)`` and ``heal()`` inject network faults,
  drawn from ``seed`` (docs/faults.md).
- ``mlink_network_factory`` — ``start(CONFIG, **options)`` for tests that need several networks or options
  decided in the test; every network started is stopped after the test.

Options: ``--mlink-config PATH``, ``--mlink-workers N|auto|station``, ``--mlink-report-dir DIR`` (each
network's final report is written there as ``<test name>.json``). Relative config paths are taken from the
current directory, then from the pytest root directory.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

__all__ = ["mlink_network", "mlink_network_factory"]


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("mlink-sim", "mlink-sim networks")
    group.addoption("--mlink-config", metavar="PATH", help="Config of the mlink_network fixture (if no marker).")
    group.addoption("--mlink-workers", metavar="N|auto|station",
                    help="Slave processes, as for 'mlink-sim up --workers' (default auto).")
    group.addoption("--mlink-report-dir", metavar="DIR", help="Write each network's final report (JSON) here.")
    parser.addini("mlink_config", "Config of the mlink_network fixture (if no marker and no --mlink-config).")


#: pytest-asyncio's setting of the event loop scope of async fixtures (docs/ci.md, "Fixtures and options")
LOOP_SCOPE_OPTION = "asyncio_default_fixture_loop_scope"


def _state_loop_scope(config: pytest.Config) -> None:
    """Where pytest-asyncio runs beside this plugin and the project leaves :data:`LOOP_SCOPE_OPTION` unset,
    pytest-asyncio warns on every run that its default will change. This plugin's fixtures are synchronous (the
    network runs in processes or threads of its own), so the scope is not this plugin's to choose: it states
    pytest-asyncio's own behaviour of today (``fixture-scope``: an async fixture's loop lives as long as the
    fixture), which changes nothing and ends the warning. A value the project sets wins; a pytest-asyncio without
    ``fixture-scope`` is left alone."""
    if not config.pluginmanager.hasplugin("asyncio"):
        return
    try:
        if config.getini(LOOP_SCOPE_OPTION):
            return
        from pytest_asyncio import plugin as asyncio_plugin
    except (ValueError, ImportError):
        return
    current = getattr(asyncio_plugin, "_MATCH_FIXTURE_SCOPE", None)
    cache = getattr(config, "_inicache", None)
    if isinstance(current, str) and isinstance(cache, dict):
        cache[LOOP_SCOPE_OPTION] = current  # what getini answers from here on


@pytest.hookimpl(tryfirst=True)  # before pytest-asyncio's own pytest_configure reads the option
def pytest_configure(config: pytest.Config) -> None:
    _state_loop_scope(config)
    config.addinivalue_line(
        "markers",
        "mlink_network(config, *, clock='real', seed=0, workers='auto', timeline=False, bringup_timeout=10.0): "
        "the network the mlink_network fixture brings up for this test (clock='virtual': in this process, on "
        "simulated time)",
    )


def _resolve(path: str | Path, config: pytest.Config) -> Path:
    p = Path(path)
    if p.is_absolute() or p.exists():
        return p
    rooted = Path(config.rootpath) / p
    return rooted if rooted.exists() else p


def _report_name(nodeid: str, index: int) -> str:
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", nodeid).strip("_")
    return f"{name}{'-' + str(index) if index else ''}.json"


class _Factory:
    def __init__(self, request: pytest.FixtureRequest) -> None:
        self.request = request
        self.started: list[Any] = []

    def __call__(self, config: str | Path, **options: Any) -> Any:
        from .harness import RunningNetwork

        pconfig = self.request.config
        options.setdefault("workers", pconfig.getoption("--mlink-workers"))
        clock = options.pop("clock", "real")
        if clock == "virtual":
            from .virtual import VirtualRunningNetwork

            net: Any = VirtualRunningNetwork(_resolve(config, pconfig), **options)
        elif clock == "real":
            net = RunningNetwork(_resolve(config, pconfig), **options)
        else:
            raise pytest.UsageError(f"mlink_network: clock must be 'real' or 'virtual', got {clock!r}")
        net.start()
        self.started.append(net)
        return net

    def stop_all(self) -> None:
        from ..metrics import write_report

        report_dir = self.request.config.getoption("--mlink-report-dir")
        for index, net in enumerate(self.started):
            report = net.close()
            if report_dir and report is not None:
                Path(report_dir).mkdir(parents=True, exist_ok=True)
                write_report(Path(report_dir) / _report_name(self.request.node.nodeid, index), report)


@pytest.fixture
def mlink_network_factory(request: pytest.FixtureRequest) -> Iterator[Callable[..., Any]]:
    """``start(CONFIG, workers="auto", timeline=False, bringup_timeout=10.0, …)`` → a running network."""
    factory = _Factory(request)
    try:
        yield factory
    finally:
        factory.stop_all()


@pytest.fixture
def mlink_network(request: pytest.FixtureRequest, mlink_network_factory: _Factory) -> Any:
    """A network brought up from the ``mlink_network`` marker's config (or ``--mlink-config`` / ``mlink_config``)."""
    marker = request.node.get_closest_marker("mlink_network")
    args: tuple[Any, ...] = marker.args if marker else ()
    options: dict[str, Any] = dict(marker.kwargs) if marker else {}
    config = args[0] if args else options.pop("config", None)
    config = config or request.config.getoption("--mlink-config") or request.config.getini("mlink_config")
    if not config:
        raise pytest.UsageError(
            "mlink_network needs a config: @pytest.mark.mlink_network('net.toml'), --mlink-config PATH, "
            "or 'mlink_config' in the pytest ini options")
    return mlink_network_factory(config, **options)
