"""The ``mlink_network`` fixture on the virtual clock (``@pytest.mark.mlink_network(CFG, clock="virtual")``):
:class:`VirtualRunningNetwork` has :class:`~mlink_sim.testing.RunningNetwork`'s methods, but the network runs in
the test's own process on simulated time (:class:`~mlink_sim.aio.run.embed.VirtualNetwork`): ``wait(2.0)`` returns at
once with two simulated seconds gone, ``wait_until`` polls in simulated time, nothing depends on how busy the
machine is, and the same seed gives the same figures."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..aio.run.embed import BringUpFailed, VirtualNetwork
from ..config import load_config, resolve_config_path
from ..operations import NetworkOperations
from ..scenario import CheckResult, StationViews
from .faults import FaultMethods, episode_dict
from .harness import NetworkNotUp, _AsyncApi
from .metrics import ReportChecks
from .wait import poll_until

__all__ = ["VirtualRunningNetwork"]

#: What the handle passes straight to the :class:`VirtualNetwork` (the bare master API, the stations, time).
_DELEGATED = frozenset({
    "prm_rd", "prm_wr", "send_config", "id_rd", "alm_rd", "alm_clr", "set_control", "view", "views", "station",
    "snapshots", "snapshot", "advance", "run_until", "step", "now", "now_ns", "reset_metrics",
})


class VirtualRunningNetwork(NetworkOperations, StationViews, ReportChecks, FaultMethods):
    """:class:`~mlink_sim.testing.RunningNetwork`'s API on simulated time; *seed* draws the network model's jitter.
    *workers*, *run_dir* and *log_level* are accepted for symmetry and have nothing to do here."""

    def __init__(self, config: str | Path, *, seed: int = 0, bringup_timeout: float = 10.0, timeline: bool = False,
                 reset_after_bringup: bool = True, state_dir: str | Path | None = None, workers: Any = None,
                 run_dir: Any = None, log_level: Any = None) -> None:
        self.config_path = resolve_config_path(config)  # a path, or the name of a shipped example
        self.config = load_config(self.config_path)
        self._options: dict[str, Any] = {"seed": seed, "bringup_timeout": bringup_timeout,
                                         "reset_after_bringup": reset_after_bringup, "state_dir": state_dir}
        self._timeline = timeline
        self.virtual: VirtualNetwork | None = None
        self.problems: list[str] = []
        self.final_report: dict[str, Any] | None = None
        self.aio = _AsyncApi(self)  # type: ignore[arg-type]  # duck-typed: the same request methods

    def start(self) -> VirtualRunningNetwork:
        """Power the stations up and bring them up (:class:`~mlink_sim.testing.NetworkNotUp` if one does not)."""
        if self.virtual is not None:
            raise RuntimeError("network already started")
        try:
            self.virtual = VirtualNetwork(self.config_path, **self._options)
        except BringUpFailed as exc:
            raise NetworkNotUp(exc.problems) from None
        self.problems = list(self.virtual.session.problems)
        if self._timeline:
            self.virtual.start_timeline()
        return self

    def close(self) -> dict[str, Any] | None:
        """DISCONNECT, stop; the final report (None if never started)."""
        if self.virtual is not None:
            self.final_report = self.virtual.close()
        return self.final_report

    def __enter__(self) -> VirtualRunningNetwork:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _net(self) -> VirtualNetwork:
        if self.virtual is None:
            raise RuntimeError("the network is not running")
        return self.virtual

    def __getattr__(self, name: str) -> Any:
        if name in _DELEGATED:
            return getattr(self._net(), name)
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")

    def _perform(self, op: str, **args: Any) -> dict[str, Any]:
        return self._net()._perform(op, **args)

    def view(self, station: int) -> Any:
        return self._net().view(station)

    @property
    def _scales(self) -> dict[int, Any]:  # type: ignore[override]  # StationViews reads the network's
        return self._net()._scales

    @property
    def _links(self) -> dict[int, Any]:  # type: ignore[override]
        return self._net()._links

    # ------------------------------------------------------------------ waiting, in simulated time
    def _fault_episode(self, station: int) -> dict[str, Any] | None:
        return episode_dict(self._net().net.fault_control.stage(station).latest(station))

    def wait(self, seconds: float) -> None:
        """Let the network cycle for *seconds* of simulated time (returns as soon as they are computed)."""
        self._net().advance(seconds)

    def wait_until(self, check: Callable[[], Any], timeout: float, interval: float = 0.02, *,
                   until: Callable[[Any], Any] | None = None) -> Any:
        """:meth:`RunningNetwork.wait_until <mlink_sim.testing.RunningNetwork.wait_until>` in simulated seconds."""
        net = self._net()
        return poll_until(check, until, timeout, interval, lambda: net.now, net.advance, " (simulated)")

    def wait_timeline(self, timeout: float | None = None) -> list[CheckResult]:
        """Run the config's timeline (``timeline=True``) to its end; returns its checks."""
        if not self._timeline:
            raise RuntimeError("the network was started without timeline=True")
        return self._net().run_timeline()

    # ------------------------------------------------------------------ figures
    def report(self) -> dict[str, Any]:
        """The report as of now (``meta.clock`` = ``"virtual"``); after :meth:`close`, the final one."""
        if self.final_report is not None:
            return self.final_report
        return self._net().report()

    def __repr__(self) -> str:
        state = "running" if self.virtual is not None and self.final_report is None else "stopped"
        return f"VirtualRunningNetwork({str(self.config_path)!r}, {len(self.config.station)} stations, {state})"
