"""What a person reads of a running network: the station figures (figures: the one definition the control
endpoint's ``status``, the trace and the web page share), the live status of ``up`` / ``master`` (status) and the
trace (trace).

May import the layers of :mod:`mlink_sim.aio` below it (virtual, slave, master, transport, timing); the control plane
above it builds its replies from the figures.
"""
