"""Real-time scheduling where the machine allows it (``--realtime``; docs/timing.md, "Real-time scheduling").

Three requests, each granted or refused on its own and reported in one line:

* **priority**: ``SCHED_FIFO`` for the calling thread (the event loop's), the master's clock above the slave
  workers (:data:`MASTER_PRIORITY`, :data:`WORKER_PRIORITY`), so that ordinary processes of the host no longer
  delay them; the kernel's RT throttling (``/proc/sys/kernel/sched_rt_runtime_us``, 95 % by default) keeps the
  machine usable even while the master spins before a deadline;
* **memory**: ``mlockall(MCL_CURRENT | MCL_FUTURE)``, so no page fault stalls a cycle;
* **CPUs**: the master on a CPU of its own (the last one), the workers on the others (:func:`cpu_plan`).

Nothing here raises: a refusal (no ``CAP_SYS_NICE``, ``RLIMIT_MEMLOCK``, a container without the capability)
is reported and the run goes on with ordinary scheduling.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

__all__ = ["MASTER_PRIORITY", "WORKER_PRIORITY", "cpu_plan", "apply"]

#: SCHED_FIFO priorities (1–99): the clock above the workers, both below the kernel's own threads (50 is the
#: priority of threaded IRQ handlers on PREEMPT_RT kernels; these stay under it).
MASTER_PRIORITY = 40
WORKER_PRIORITY = 30

_MCL_CURRENT, _MCL_FUTURE = 1, 2


def cpu_plan(cpus: set[int] | None = None) -> tuple[set[int], set[int]]:
    """``(master CPUs, worker CPUs)``: the master alone on the highest CPU, the workers on the rest; one CPU is
    shared by both."""
    cpus = set(cpus if cpus is not None else os.sched_getaffinity(0))
    if len(cpus) < 2:
        return cpus, cpus
    master = max(cpus)
    return {master}, cpus - {master}


def apply(priority: int, cpus: set[int] | None = None) -> str:
    """Ask for SCHED_FIFO *priority*, locked memory and the *cpus*; return what was granted, e.g.
    ``"SCHED_FIFO 40, memory locked, CPU 1"`` or ``"SCHED_FIFO refused (Operation not permitted), …"``."""
    parts = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        parts.append(f"SCHED_FIFO {priority}")
    except (OSError, AttributeError) as exc:
        parts.append(f"SCHED_FIFO refused ({_why(exc)})")
    parts.append(_lock_memory())
    if cpus:
        try:
            os.sched_setaffinity(0, cpus)
            parts.append(f"CPU {','.join(map(str, sorted(cpus)))}")
        except (OSError, AttributeError) as exc:
            parts.append(f"CPU affinity refused ({_why(exc)})")
    return ", ".join(parts)


def _lock_memory() -> str:
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.mlockall(_MCL_CURRENT | _MCL_FUTURE) != 0:
            return f"memory lock refused ({os.strerror(ctypes.get_errno())})"
    except (OSError, AttributeError) as exc:
        return f"memory lock refused ({_why(exc)})"
    return "memory locked"


def _why(exc: BaseException) -> str:
    return os.strerror(exc.errno) if isinstance(exc, OSError) and exc.errno else type(exc).__name__
