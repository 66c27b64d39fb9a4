"""Keeping time: the master's cycle timer (ticker), Linux timerfd (timerfd), real-time scheduling and the yield
after a send (realtime), the slave worker's arrival poll (arrival) and the garbage collector kept off the cycle
(heap).

The lowest layer of :mod:`mlink_sim.aio`: imports no other part of it.
"""
