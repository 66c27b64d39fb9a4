"""The virtual clock and the in-memory network: the event loop on simulated time (vclock, its timer queue vqueue)
and the fabric that carries the datagrams between the masters and the card cores (fabric).

May import the slave layer's state files (the cards' EEPROM images) and :mod:`mlink_sim.impair`; not the master
or run layers.
"""

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the master's end of the fabric is the port the master runner holds (checked by mypy, never run)
    from ..transport.ports import DatagramPort
    from .fabric import FabricPort

    def _port(port: FabricPort) -> DatagramPort:
        return port
