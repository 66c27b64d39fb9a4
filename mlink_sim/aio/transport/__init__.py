"""Sockets: what the layer needs of one (ports: the Protocols every socket and stand-in satisfies), UDP endpoints
and the loop helpers (udp), the batched system calls ``sendmmsg``/``recvmmsg`` with UDP
segmentation offload (mmsg, msghdr, gro, sendlayout), a capture's tap on them (tapped) and the impairment delay
line in front of a socket (impaired).

May import the timing layer (the arrival poll, the timerfd), :mod:`mlink_sim.capture` (the tap) and
:mod:`mlink_sim.impair`; nothing of the slave, master, virtual or run layers above it.
"""
