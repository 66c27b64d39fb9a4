"""The control plane of a running network, a standalone slave or the impairing proxy: the control endpoint and its
client (endpoint, with its token), the network's operations (network), a slave's (slave), the faults' and the
impairments' (faults), the run's events (events) and the timeline's driver (timeline) — every operation one handler,
whichever surface asks for it (docs/control.md).

May import the layers of :mod:`mlink_sim.aio` below it (present, virtual, slave, master, transport, timing).
"""
