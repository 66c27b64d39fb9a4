"""The master on a real network (runner): :class:`~mlink_sim.master.MasterCore` driven by the cycle timer over one
UDP socket, with awaitable requests.

May import the transport and timing layers and the sans-I/O cores (master, faults, wire); not the slave, virtual
or run layers.
"""

from .runner import Master, run

__all__ = ["Master", "run"]
