"""The master API of a whole network, routed per station to the master of its link (:class:`NetworkApi`), and
the masters' plans of a config (:func:`build_plans`).

Touches: the masters (their requests and INV_CTL fields), the slave workers' control endpoints (a drive's activity),
the fault control of the run.
"""

from __future__ import annotations

from typing import Any

from ..._log import get_logger
from ...config import Config
from ...scenario.values import restart_profile, speed_scale
from ...wire import Link
from ..control.faults import FaultControl

__all__ = ["NetworkApi", "build_plans"]

log = get_logger("mlink_sim.session")


def build_plans(config: Config) -> dict[Link, Any]:
    """One :class:`~mlink_sim.master.plan.NetworkPlan` per link present in the config."""
    from ...master.plan import NetworkPlan, StationPlan

    by_link: dict[Link, list[Any]] = {}
    for st in config.station:
        assert st.link is not None
        plan = StationPlan(
            address=st.address,
            link=st.link,
            data_size=st.frame_size or 0,
            com_tim=st.com_tim or 0,
            sync=st.sync,
            subcmd=bool(st.subcmd),  # the config's validation fills it in
            name=st.name or "",
            card=st.card,
            et3_syncmode_table19=bool(st.options.get("et3_syncmode_table19", False)),
            hz_per_count=speed_scale(st).to_hz(1),  # the views' output_hz (o1-03 / n035 units)
            **restart_profile(st),
        )
        by_link.setdefault(st.link, []).append(plan)
    return {
        link: NetworkPlan(link=link, tcycle_ns=config.network.transmission_cycle, stations=tuple(stations),
                          answer_window_ns=config.network.absorb_ns)
        for link, stations in by_link.items()
    }



class NetworkApi:
    """The master API of a whole network: every call is routed to the master of the station's link.

    Keeps each station's INV_CTL fields, so that a partial update (``set_control(0x21, ef0=True)``) leaves the
    other fields as they were. The handlers of the network's operations (:mod:`mlink_sim.aio.control.network`) act through it."""

    def __init__(self, config: Config, masters: dict[Link, Any], workers: dict[int, Any]) -> None:
        self.masters = masters
        self.workers = workers
        # the config's validation fills every station's link in
        self.by_station = {st.address: masters[st.link] for st in config.station}  # type: ignore[index]
        self._controls: dict[int, dict[str, Any]] = {st.address: {} for st in config.station}
        self.fault_control = FaultControl(self)  #: station, master and drive faults (docs/faults.md)

    def master(self, station: int) -> Any:
        """The :class:`~mlink_sim.aio.master.runner.Master` serving *station*."""
        return self.by_station[station]

    def view(self, station: int) -> Any:
        """The master's :class:`~mlink_sim.master.StationView` of *station* (state, phase, status, alarms …)."""
        return self.by_station[station].view(station)

    async def drive_activity(self, station: int) -> Any:
        """What *station*'s drive model is doing (:class:`~mlink_sim.drive.activity.DriveActivity`): read on the
        card core in this process (the virtual clock), else asked of its slave worker; None when the slave runs
        elsewhere (``mlink-sim master``) or does not answer."""
        worker = self.workers.get(station)
        return None if worker is None else await worker.drive_activity(station)

    def alarms_seen(self, station: int) -> dict[str, int]:
        """Every alarm *station* raised so far, as the master saw it: name -> how many times."""
        return dict(self.by_station[station].alarms_seen.get(station, {}))

    def views(self) -> dict[int, Any]:
        out: dict[int, Any] = {}
        for m in self.masters.values():
            out.update(m.views())
        return out

    def control(self, station: int) -> dict[str, Any]:
        return dict(self._controls[station])

    def set_control(self, station: int, **fields: Any) -> None:
        """Update the cyclic INV_CTL fields of *station* (forward, reverse, speed_ref, fault_reset, ef0 …)."""
        merged = self._controls[station]
        merged.update(fields)
        self.by_station[station].set_control(station, **merged)

    async def prm_rd(self, station: int, register: int | str, size: int = 2) -> Any:
        """PRM_RD by name (a ``ParamValue`` in units) or register number (raw): ``Master.prm_rd``."""
        return await self.by_station[station].prm_rd(station, register, size)

    async def prm_wr(self, station: int, register: int | str, value: Any, size: int = 2) -> Any:
        """PRM_WR by name (engineering units, range-checked) or register number (raw): ``Master.prm_wr``."""
        return await self.by_station[station].prm_wr(station, register, value, size=size)

    async def config(self, station: int, mode: int = 0) -> Any:
        return await self.by_station[station].config(station, mode)

    async def id_rd(self, station: int, code: int, offset: int = 0, size: int = 8) -> Any:
        return await self.by_station[station].id_rd(station, code, offset, size)

    async def alm_rd(self, station: int, mode: int = 0, index: int = 0) -> Any:
        return await self.by_station[station].alm_rd(station, mode, index)

    async def alm_clr(self, station: int) -> Any:
        return await self.by_station[station].alm_clr(station)

    async def disconnect(self, station: int) -> Any:
        return await self.by_station[station].disconnect(station)

    async def reconnect(self, station: int) -> Any:
        self.by_station[station].connect(station)

    #: the session that owns the impairment layer (``impair``/``heal``), set by it
    faults: Any = None

    def impair(self, station: int | None, spec: Any, name: str | None = None) -> str:
        """Start the network impairment *spec* (an :class:`~mlink_sim.impair.Impairment`) on *station* (None:
        every station) as *name* (None: a made name, replacing the unnamed one there; docs/faults.md); its name."""
        return str(self._faults().impair(station, spec, name))

    def heal(self, station: int | None = None, name: str | None = None) -> list[str]:
        """End every network impairment of *station* (None: of every station), or the one called *name*; the
        names that ended."""
        return list(self._faults().heal(station, name))

    def _faults(self) -> Any:
        if self.faults is None:
            raise RuntimeError("this network has no impairment layer")
        return self.faults

    def kill_slave(self, station: int) -> bool:
        worker = self.workers.get(station)
        if worker is None:
            return False
        log.warning("killing_slave", station=f"{station:#04x}", pid=worker.pid)
        worker.kill()
        return True

    async def fault(self, station: int, fault: Any) -> Any:
        """Start *fault* (a :mod:`mlink_sim.faults.spec` value) on *station* now; returns its
        :class:`~mlink_sim.faults.Episode` (recovery measured after its end). Drive faults need the slaves of
        ``up`` or the virtual clock (:class:`~mlink_sim.aio.slave.faults.PlantError` otherwise)."""
        return await self.fault_control.inject(station, fault)
