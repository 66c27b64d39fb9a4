"""mlink-sim: a real-time MECHATROLINK-I/II/III master/slave simulator.

Layers (see docs/architecture.md):

* ``mlink_sim.wire``    – datagram envelope and frame codecs (bytes <-> frames), pure
* ``mlink_sim.params``  – parameter tables per drive family, pure data
* ``mlink_sim.drive``   – VFD dynamics model stepped with explicit time, pure
* ``mlink_sim.cards``   – SI-T3 / SI-ET3 / SI-T/V7 state machines (datagram + now -> datagram), pure
* ``mlink_sim.master``  – master core (sans-I/O) and its async API
* ``mlink_sim.aio``     – asyncio/uvloop transport and timing: moves bytes, keeps time
* ``mlink_sim.cli``     – command line and process supervision
* ``mlink_sim.profiles`` – the option cards, one record each (key, label, tables, links), read by every layer
"""

from . import _accel

__version__ = "0.1.0"
__all__ = ["__version__"]

# compiled or pure-Python cores, decided once before any core module is imported (docs/architecture.md,
# "Compiled cores (mypyc)"; MLINK_PURE=1 forces pure)
_accel.select()
