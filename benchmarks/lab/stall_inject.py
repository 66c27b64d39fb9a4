"""Host stalls on purpose: stop processes with SIGSTOP for a while, periodically, and always continue them.

The helper of :mod:`benchmarks.lab.recovery`, which starts it for each window it disturbs:

    python -m benchmarks.lab.stall_inject STALL_NS EVERY_NS START_NS END_NS PID… [--later LAG_NS PID…]

stops every PID for STALL_NS (SIGSTOP, then SIGCONT) every EVERY_NS, the first at START_NS + EVERY_NS, the last
ending by END_NS (times on CLOCK_MONOTONIC, which every process of the host shares), then prints one JSON line:
``{"stalls_ns": [each stall as measured], "scheduling": "SCHED_FIFO 60" or why not}``. The PIDs after
``--later`` are stopped with the others and continued LAG_NS after them: a host stall after which one process runs
before another (the slave workers' tick before the master's catch-up). It imports nothing but the
standard library (and :mod:`benchmarks.common`, which does the same), so that starting it costs the measured
processes next to no CPU. It asks for SCHED_FIFO above
``mlink-sim up --realtime``'s priorities and for every CPU, so that what it stops cannot delay its SIGCONT; refused,
it runs as it is and says so. Every process it stopped is continued whichever way it ends: its end, SIGTERM or
SIGINT (exit 143 / 130, no report), or its parent's death (it asks for SIGTERM then). Exit 2 for bad arguments.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import time

from mlink_sim.aio.run.supervisor import die_with_parent

__all__ = ["PRIORITY", "inject", "signal_all"]

PRIORITY = 60  #: SCHED_FIFO priority: above the master's 40 and the workers' 30 (``mlink_sim.aio.timing.realtime``)


def signal_all(pids: list[int], sig: int) -> None:
    """*sig* to each of *pids*; one already gone is skipped."""
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, sig)


def inject(pids: list[int], stall_ns: int, every_ns: int, start_ns: int, end_ns: int,
           later: list[int] | None = None, lag_ns: int = 0) -> list[int]:
    """Stop *pids* (and *later*) for *stall_ns* every *every_ns* from *start_ns* + *every_ns* until *end_ns*, then
    wait for *end_ns*; *later* are continued *lag_ns* after *pids*. Returns each stall's measured length (ns, from
    the last SIGSTOP sent to the first SIGCONT sent). Every process stopped is continued however this ends (an
    exception included)."""
    later = later or []
    every = pids + later
    lengths: list[int] = []
    at = start_ns + every_ns
    try:
        while at + stall_ns + lag_ns <= end_ns:
            time.sleep(max(0, at - time.monotonic_ns()) / 1e9)
            signal_all(every, signal.SIGSTOP)
            stopped = time.monotonic_ns()
            try:
                time.sleep(stall_ns / 1e9)
            finally:
                signal_all(pids, signal.SIGCONT)
            lengths.append(time.monotonic_ns() - stopped)
            if later:
                try:
                    time.sleep(lag_ns / 1e9)
                finally:
                    signal_all(later, signal.SIGCONT)
            at += every_ns
        time.sleep(max(0, end_ns - time.monotonic_ns()) / 1e9)
    finally:
        signal_all(every, signal.SIGCONT)
    return lengths


def _prepare() -> str:
    """Die with the parent, every CPU, SCHED_FIFO where granted; returns what scheduling it got."""
    die_with_parent()
    with contextlib.suppress(OSError):
        os.sched_setaffinity(0, range(os.cpu_count() or 1))
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
        return f"SCHED_FIFO {PRIORITY}"
    except (OSError, AttributeError) as exc:
        return f"ordinary scheduling (SCHED_FIFO refused: {exc})"


def main(argv: list[str]) -> int:
    try:
        cut = argv.index("--later") if "--later" in argv else len(argv)
        stall_ns, every_ns, start_ns, end_ns, *pids = (int(a) for a in argv[:cut])
        lag_ns, *later = (int(a) for a in argv[cut + 1:]) if cut < len(argv) else (0,)
        if not pids or stall_ns <= 0 or lag_ns < 0 or every_ns <= stall_ns + lag_ns or (cut < len(argv) and not later):
            raise ValueError
    except ValueError:
        print("usage: python -m benchmarks.lab.stall_inject STALL_NS EVERY_NS START_NS END_NS PID… [--later LAG_NS PID…] "
              "(STALL_NS > 0, EVERY_NS > STALL_NS + LAG_NS)", file=sys.stderr)
        return 2
    for sig, code in ((signal.SIGTERM, 143), (signal.SIGINT, 130)):
        signal.signal(sig, lambda *_, code=code: sys.exit(code))  # raised in the sleep: inject's finally continues
    scheduling = _prepare()
    lengths = inject(pids, stall_ns, every_ns, start_ns, end_ns, later, lag_ns)
    print(json.dumps({"stalls_ns": lengths, "scheduling": scheduling}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
