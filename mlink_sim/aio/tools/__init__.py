"""Stand-alone network tools behind the command line: the probe (``mlink-sim probe``, the testbed's reachability
check) and the impairing proxy (``mlink-sim proxy``). They live here rather than in :mod:`mlink_sim.cli` because
:mod:`mlink_sim.testbed`, below the command line, runs the probe too.

May import the transport layer; independent of the run layer beside it.
"""
