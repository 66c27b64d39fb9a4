"""Micro-benchmarks: the CPU one piece of the simulator takes (the drive model's step, an exchange of the cores, the
latency histogram, the impairment layer, the capture, the virtual clock), each run on its own, without a network
of processes. benchmarks/README.md gives their commands."""
