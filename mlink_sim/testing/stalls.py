"""Telling a run that failed for the host's reasons from one that failed for mlink-sim's (docs/ci.md).

A host stall longer than the bound the host-stall policy absorbs (100 ms by default, docs/timing.md "Host stalls")
is, for the stations, a lost connection: they recover by themselves (docs/master.md), but a timeline check due
before the drives are back at speed can fail. Every failed check names the stalls of the three seconds before it
(:meth:`mlink_sim.metrics.stalls.StallLog.describe_near`). :func:`beyond_the_bound` reads those sentences back:
when *every* failed check names a stall beyond the bound, the run says nothing about the simulator, and a test
on a busy runner may skip it, naming them. Any other failure is a failure.

    failed = [f"{c.what}: {c.detail}" for c in net.wait_timeline() if not c.ok]
    if reason := beyond_the_bound(failed, net.report()["host"]["bound"]):
        pytest.skip(reason)
    assert failed == []
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from ..config import parse_duration_ns
from ..metrics.stalls import longest_named_ms

__all__ = ["beyond_the_bound", "run_beyond_the_bound"]

_FAIL = re.compile(r"^\s*FAIL\s+(.*)$", re.MULTILINE)
_BOUND = re.compile(r"policy absorbs up to (\S+?)\)")


def beyond_the_bound(failed: Iterable[str], bound_ns: int) -> str | None:
    """The reason to skip when every text in *failed* (a failed check's description and detail) names a host
    stall longer than *bound_ns*; None when one of them does not, or when nothing failed."""
    texts = list(failed)
    bound_ms = bound_ns / 1e6
    if not texts or bound_ns <= 0 or not all(longest_named_ms(t) > bound_ms for t in texts):
        return None
    return (f"the host stalled beyond the {bound_ms:g} ms bound the host-stall policy absorbs before every failed "
            "check: " + " | ".join(texts))


def run_beyond_the_bound(output: str) -> str | None:
    """:func:`beyond_the_bound` for the output of ``mlink-sim up`` / ``master``: its ``FAIL`` lines, and the bound
    its summary line states ("policy absorbs up to 100ms"); None under the strict policy or without failures."""
    bound = _BOUND.search(output)
    if bound is None:
        return None
    return beyond_the_bound(_FAIL.findall(output), parse_duration_ns(bound.group(1)))
