"""The network run: ``mlink-sim up`` / ``master`` (network), the session that opens the workers and the masters
(session), its virtual-clock variant (virtual_session) and the embedded API on it (embed), the timeline (scenario,
faultchecks), the slave worker processes (supervisor), the live status (status), the control endpoint and its
client (control), the faults on a running network (faults) and the trace's sampler (trace).

The top layer of :mod:`mlink_sim.aio` with tools: may import every layer below it (virtual, slave, master,
transport, timing).
"""
