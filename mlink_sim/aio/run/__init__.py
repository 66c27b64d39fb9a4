"""The network run — orchestration and supervision: ``mlink-sim up`` / ``master`` and their phases (network), the
verdict and the summary (verdict), the session that opens the workers and the masters (session), the master API
routed per station (netapi), the session on the virtual clock (virtual_session) and the embedded network on it
(embed), the slave worker processes (supervisor) and the web server's process (webproc).

The top layer of :mod:`mlink_sim.aio` with tools: may import every layer below it (control, present, virtual,
slave, master, transport, timing).
"""
