"""Real-time scheduling where the machine allows it (``--realtime``; docs/timing.md, "Real-time scheduling").

Four requests, each granted or refused on its own and reported in one line:

* **priority**: ``SCHED_FIFO`` for the calling thread (the event loop's), the master's clock above the slave
  workers (:data:`MASTER_PRIORITY`, :data:`WORKER_PRIORITY`), so that ordinary processes of the host do not
  delay them; the kernel's RT throttling (``/proc/sys/kernel/sched_rt_runtime_us``, 95 % by default) keeps the
  machine usable even while the master spins before a deadline;
* **memory**: ``mlockall(MCL_CURRENT | MCL_FUTURE)``, so no page fault stalls a cycle;
* **wake-up latency**: the kernel's PM QoS request for a CPU wake-up latency of 0 µs (:func:`hold_wakeup_latency`,
  ``/dev/cpu_dma_latency``, as ``cyclictest`` does), held until the process exits: an idle CPU polls instead of
  halting, so a datagram or a timer does not wait for a halted CPU to wake up. On a virtual machine that wake-up
  is the hypervisor's, a large part of a short cycle's exchange (docs/timing.md, "Real-time scheduling";
  docs/performance.md, "Timer wake-up"). The price is power: the machine's idle CPUs spin while the network runs;
* **CPUs**: the master on a CPU of its own (the last one), the workers on the others (:func:`cpu_plan`), *only
  where the wake-up latency is held*. Apart, every command and every answer wakes the other CPU; without the hold
  that CPU has halted, and the wake-up lengthens every round trip (docs/performance.md, "Timer wake-up"), so an
  ordinary user, whom the placement would be the one thing granted, is not placed. Left to itself the kernel runs
  the master and the worker it wakes on one CPU.
  The plan is made from the CPUs the process had before it first placed itself (:func:`allowed_cpus`): a session
  opened after the master took its CPU would otherwise put its workers on that same CPU, under the master's
  higher priority. CPUs the user chose (``--cpus``) are taken with or without the rest (:func:`pin`): a swarm
  service or a process started by hand has no cpuset of its own, so it places itself.

Besides, under ordinary scheduling too: :func:`yield_after_send`, the one ``os.sched_yield`` a process makes right
after it sent what wakes another process; and :func:`background_thread`, the scheduling of a thread that works
beside the loop (an EEPROM image's write): a thread inherits its creator's ``SCHED_FIFO``, and at the loop's own
priority it would hold the CPU until it blocks, while the loop's commands wait.

Nothing here raises: a refusal (no ``CAP_SYS_NICE``, ``RLIMIT_MEMLOCK``, a container without the capability, no
access to ``/dev/cpu_dma_latency``) is reported and the run goes on with ordinary scheduling.

Touches: this process's scheduling policy, CPU affinity and locked memory, and /dev/cpu_dma_latency.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import struct
from collections.abc import Callable

from ...units import format_cpus, parse_cpus

__all__ = ["yield_after_send", "background_thread", "MASTER_PRIORITY", "WORKER_PRIORITY", "PM_QOS_PATH", "allowed_cpus", "cpu_plan", "format_cpus",
           "parse_cpus", "apply", "pin", "withdraw", "unplace_child", "hold_wakeup_latency", "wakeup_latency_held",
           "wakeup_latency_limit", "release_wakeup_latency"]

#: SCHED_FIFO priorities (1–99): the clock above the workers, both below the kernel's own threads (50 is the
#: priority of threaded IRQ handlers on PREEMPT_RT kernels; these stay under it).
MASTER_PRIORITY = 40
WORKER_PRIORITY = 30

_MCL_CURRENT, _MCL_FUTURE = 1, 2

#: The CPU latency QoS device (Linux, Documentation/power/pm_qos_interface.rst): a process that holds it open
#: with a signed 32-bit value written to it has a request for at most that many µs of wake-up latency on every CPU;
#: closing it (or exiting) withdraws the request.
PM_QOS_PATH = "/dev/cpu_dma_latency"
_held: dict[str, int] = {}  # path -> the open descriptor that holds this process's request
#: The CPUs this process could use before :func:`apply` first narrowed its affinity: what :func:`cpu_plan` plans
#: on, so that a network opened after the process placed itself (a second ``run_up`` of one program) does not
#: plan its workers onto the master's single CPU.
_allowed: set[int] | None = None
_GRANTED = "CPU wake-up latency 0 µs"
_UNPLACED = "CPUs left to the kernel (no wake-up latency held)"


def yield_after_send() -> Callable[[], None] | None:
    """``os.sched_yield``, to be called by a process that has just sent the answers of a read and still has work
    before it sleeps (a packed worker: its cards' :meth:`Bus.settle <mlink_sim.aio.slave.bus.Bus.settle>`, a sizable
    part of a 1 ms cycle for a full line); ``None`` where the call does not exist.

    Why: Linux wakes the reader of a local socket *synchronously* (``WF_SYNC``): the scheduler takes the waker for
    a process about to sleep and may queue the woken one behind it, on the waker's CPU. The worker does not sleep
    after its send; it settles. Without the yield the master reads its answers only after the settle, late, while
    the other CPU idles. Yielding once after the send lets the master run (or be moved) at once; where nothing else
    waits on that CPU it returns at once (a system call). Without it a line of many stations misses more
    exchanges and its RTT tail grows (docs/performance.md, "Tried, not kept": no yield after the worker's send).
    The master's clock calls
    it too, between two cycles of a catch-up after a stall, and the arrival poll between two empty reads, for the
    same reason (docs/timing.md, "The catch-up yields")."""
    return getattr(os, "sched_yield", None)


def background_thread() -> None:
    """Make the calling thread a background one: ``SCHED_IDLE`` (ordinary scheduling where that is refused), so that
    the event loop's thread preempts it the moment a datagram or its clock wakes it (a thread pool's
    ``initializer``). Linux schedules threads one by one (``sched_setscheduler`` of 0 is the calling thread); a
    thread the loop's real-time thread starts inherits its ``SCHED_FIFO`` priority, and at the same priority on the
    same CPU the loop waits until the thread blocks. Nothing raises."""
    for policy in (getattr(os, "SCHED_IDLE", None), getattr(os, "SCHED_OTHER", None)):
        if policy is None:
            continue
        try:
            os.sched_setscheduler(0, policy, os.sched_param(0))
            return
        except OSError:
            continue


def cpu_plan(cpus: set[int] | None = None) -> tuple[set[int], set[int]]:
    """``(master CPUs, worker CPUs)`` of *cpus* (default: :func:`allowed_cpus`): the master alone on the highest
    CPU, the workers on the rest; one CPU is shared by both."""
    cpus = set(cpus if cpus is not None else allowed_cpus())
    if len(cpus) < 2:
        return cpus, cpus
    master = max(cpus)
    return {master}, cpus - {master}


def allowed_cpus() -> set[int]:
    """The CPUs this process may use: its affinity from before :func:`apply` first placed it, else the present one."""
    return set(_allowed) if _allowed is not None else os.sched_getaffinity(0)


def apply(priority: int, cpus: set[int] | None = None, *, placed: bool = False) -> str:
    """Ask for SCHED_FIFO *priority*, locked memory, a CPU wake-up latency of 0 µs and, if that is held or the
    user chose them (*placed*, ``--cpus``), the *cpus*; return what was granted, e.g. ``"SCHED_FIFO 40, memory
    locked, CPU wake-up latency 0 µs, CPU 1"``, ``"SCHED_FIFO refused (Operation not permitted), …"`` or ``"…, CPU
    wake-up latency refused (Permission denied), CPUs left to the kernel (no wake-up latency held)"`` (see the
    module docstring)."""
    parts = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        parts.append(f"SCHED_FIFO {priority}")
    except (OSError, AttributeError) as exc:
        parts.append(f"SCHED_FIFO refused ({_why(exc)})")
    parts.append(_lock_memory())
    parts.append(hold_wakeup_latency())
    if cpus and not placed and not wakeup_latency_held():
        parts.append(_UNPLACED)
    elif cpus:
        parts.append(pin(cpus))
    return ", ".join(parts)


def pin(cpus: set[int]) -> str:
    """Run this process on *cpus* only (``sched_setaffinity``; ``--cpus`` with or without ``--realtime``), those
    of them it may use (:func:`allowed_cpus`: a container's cpuset, ``taskset``); what was granted, e.g. ``"CPU
    0,1"``, ``"CPU 1 (CPU 7 refused: not among those allowed, 0,1)"`` or ``"CPU affinity refused (CPU 7 not
    among those allowed, 0,1)"``. Nothing raises."""
    global _allowed
    allowed = allowed_cpus()
    granted, refused = cpus & allowed, cpus - allowed
    if not granted:
        return f"CPU affinity refused (CPU {format_cpus(refused)} not among those allowed, {format_cpus(allowed)})"
    try:
        if _allowed is None:
            _allowed = os.sched_getaffinity(0)
        os.sched_setaffinity(0, granted)
    except (OSError, AttributeError) as exc:
        return f"CPU affinity refused ({_why(exc)})"
    note = f" (CPU {format_cpus(refused)} refused: not among those allowed, {format_cpus(allowed)})" if refused else ""
    return f"CPU {format_cpus(granted)}{note}"


def withdraw() -> None:
    """Undo :func:`apply` in this process: ordinary scheduling, every CPU :func:`allowed_cpus` gives, the CPU
    wake-up latency request withdrawn (locked memory stays locked). For a program that asked, was refused a part and
    runs on without any of it (a benchmark whose floor and network must run alike). Nothing raises."""
    release_wakeup_latency()
    unplace_child()


def unplace_child() -> None:
    """Ordinary scheduling and every CPU :func:`allowed_cpus` gives to the calling process, whatever it was
    granted: in a child between fork and exec (``preexec_fn``), and in :func:`withdraw`. A worker started by a
    master that holds SCHED_FIFO 40 on its own CPU (a restart during the run) otherwise ran its start-up there at
    the master's priority, which the master cannot preempt: its clock stalled for the whole start-up
    (docs/timing.md, "Real-time scheduling"; docs/performance.md, "Timer wake-up"). The worker then asks for its own (``mlink-sim slave --realtime --cpus``). Nothing
    raises (a refusal leaves what was inherited)."""
    if _allowed is None and os.sched_getscheduler(0) == os.SCHED_OTHER:
        return  # never placed: nothing to undo
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        os.sched_setaffinity(0, allowed_cpus())
    except OSError:
        pass


def hold_wakeup_latency(path: str | None = None) -> str:
    """Request a CPU wake-up latency of 0 µs from the kernel's PM QoS (*path*, default :data:`PM_QOS_PATH`), held
    until this process exits or :func:`release_wakeup_latency`; what was granted, e.g. ``"CPU wake-up latency
    0 µs"`` or ``"CPU wake-up latency refused (Permission denied)"``. Asking again while held changes nothing."""
    path = PM_QOS_PATH if path is None else path
    if path in _held:
        return _GRANTED
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CLOEXEC)
    except OSError as exc:
        return f"CPU wake-up latency refused ({_why(exc)})"
    try:
        os.write(fd, struct.pack("=i", 0))  # a signed 32-bit value in µs (a 10-character hex string is the other form)
    except OSError as exc:
        os.close(fd)
        return f"CPU wake-up latency refused ({_why(exc)})"
    _held[path] = fd
    return _GRANTED


def wakeup_latency_held(path: str | None = None) -> bool:
    """True while this process holds the request of :func:`hold_wakeup_latency`."""
    return (PM_QOS_PATH if path is None else path) in _held


def wakeup_latency_limit(path: str | None = None) -> int | None:
    """The CPU wake-up latency the kernel holds now for the whole system, in µs: the least of every process's
    request (this one's, ``mlink-sim up --realtime``'s, a benchmark's, a tuning daemon's); 0 means idle
    CPUs poll. None where it cannot be read (the device is root's only, or missing). Opening the device adds a
    request of the default value, which changes nothing, and closing it withdraws that again."""
    try:
        with open(PM_QOS_PATH if path is None else path, "rb", buffering=0) as device:
            raw = device.read(4)
    except OSError:
        return None
    return struct.unpack("=i", raw)[0] if len(raw) == 4 else None


def release_wakeup_latency(path: str | None = None) -> None:
    """Withdraw the request of :func:`hold_wakeup_latency` (nothing if none is held)."""
    fd = _held.pop(PM_QOS_PATH if path is None else path, None)
    if fd is not None:
        os.close(fd)


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
