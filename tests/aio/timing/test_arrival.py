"""mlink_sim.aio.timing.arrival.ArrivalPoll: the cycle learned from the bursts' arrivals (their median gap), the poll
set a lead before the next burst is due (a cycle after the last, or after the last one's due time when a late wake-up
read it), none above ``max_period_ns``; on a real socket the bursts are read in the poll and every datagram is
handed over once. The setting's parser: mlink_sim.config.units.parse_arrival_poll."""

from __future__ import annotations

import asyncio
import socket
import time

import pytest

from mlink_sim.aio.timing.timerfd import timerfd_supported
from mlink_sim.aio.timing.arrival import LATE_SAMPLES, LEAD_MARGIN_NS, QOS_RECHECK_NS, SAMPLES, ArrivalPoll
from mlink_sim.aio.transport.udp import open_batch_endpoint
from mlink_sim.config.units import AUTO_POLL_LEAD_NS, AUTO_POLL_MAX_PERIOD_NS, parse_arrival_poll

pytestmark = pytest.mark.skipif(not timerfd_supported(), reason="no timerfd here")

US = 1_000


@pytest.fixture(autouse=True)
def _cpus_halt(monkeypatch):
    """Idle CPUs halt, whatever this machine holds now (a CI runner's own PM QoS request must not decide)."""
    monkeypatch.setattr("mlink_sim.aio.timing.arrival.wakeup_latency_limit", lambda: None)


class _Recorder:
    """An ArrivalPoll fed arrival times by hand, on a loop that never runs: what it sets is read, never fired."""

    def __init__(self, loop: asyncio.AbstractEventLoop, lead_ns: int, max_period_ns: int | None) -> None:
        self.poll = ArrivalPoll(loop, lambda: False, lead_ns, max_period_ns)
        self.set: list[int] = []

    def feed(self, times: list[int]) -> None:
        for t in times:
            before = self.poll.poll_at_ns
            self.poll.arrived(t)
            if self.poll.armed and self.poll.poll_at_ns != before:
                self.set.append(self.poll.poll_at_ns)


def test_the_cycle_is_the_median_gap_and_the_poll_is_set_a_lead_before_the_next_burst() -> None:
    loop = asyncio.new_event_loop()
    r = _Recorder(loop, 80 * US, 500 * US)
    try:
        start = 1_000_000_000
        # 250 µs bursts, one read late by 30 µs and one burst missed (a 500 µs gap): the median is the cycle
        times = [start + k * 250 * US for k in range(SAMPLES + 2) if k != 7]
        times[3] += 30 * US
        r.feed(times[:SAMPLES + 1])
        assert r.poll.period_ns == 250 * US and r.poll.armed
        assert r.set == [times[SAMPLES] + 250 * US - 80 * US]  # nothing set before the cycle was known
        r.feed([times[SAMPLES] + 5 * US])  # the rest of the same burst, read a moment later: nothing changes
        assert len(r.set) == 1
    finally:
        r.poll.close()
        loop.close()


def test_a_late_wake_up_keeps_the_phase_and_a_burst_far_from_its_time_resets_it() -> None:
    loop = asyncio.new_event_loop()
    r = _Recorder(loop, 80 * US, None)
    try:
        t = [k * 250 * US + 10**9 for k in range(SAMPLES + 1)]
        r.feed(t)
        due = t[-1] + 250 * US
        r.feed([due + 60 * US])  # read by the reader 60 µs after its due time (≤ the lead): a late wake-up
        assert r.set[-1] == due + 250 * US - 80 * US
        due += 250 * US
        r.feed([due + 120 * US])  # 120 µs late (> the lead): the master's own lateness; a cycle after this read
        assert r.set[-1] == due + 120 * US + 250 * US - 80 * US
        due += 120 * US + 250 * US
        r.poll._polling = True  # read in the poll: at its arrival, the phase follows it
        r.feed([due + 20 * US])
        r.poll._polling = False
        assert r.set[-1] == due + 20 * US + 250 * US - 80 * US
    finally:
        r.poll.close()
        loop.close()


def test_no_poll_above_the_longest_cycle() -> None:
    loop = asyncio.new_event_loop()
    r = _Recorder(loop, 80 * US, 500 * US)  # "auto": polls only up to 500 µs
    lead = _Recorder(loop, 900 * US, None)  # a lead given: at any cycle, at most half a cycle ahead
    try:
        r.feed([10**9 + k * 1_000_000 for k in range(2 * SAMPLES + 1)])
        assert r.poll.period_ns == 1_000_000 and not r.poll.armed and r.set == []
        lead.feed([10**9 + k * 1_000_000 for k in range(SAMPLES + 1)])
        assert lead.poll.armed and lead.set == [10**9 + (SAMPLES + 1) * 1_000_000 - 500 * US]
    finally:
        r.poll.close()
        lead.poll.close()
        loop.close()


async def test_bursts_on_a_socket_are_read_in_the_poll_and_none_is_lost() -> None:
    """Bursts of 3 datagrams every 4 ms from another thread, read with a 1 ms lead (2 ms of poll around each):
    once the cycle is learned the poll reads bursts (not only the reader's wake-ups), and every datagram reaches
    the receiver once."""
    got: list[bytes] = []
    ep = await open_batch_endpoint(lambda batch: got.extend(d for d, _ in batch))
    assert ep.poll_arrivals(parse_arrival_poll("1ms")) and ep.poll is not None
    assert ep.poll_arrivals(parse_arrival_poll("off"))  # set once: the first setting stays
    bursts = SAMPLES + 12
    expected = sorted(bytes([k, i]) for k in range(bursts) for i in range(3))

    sent_at: list[int] = []

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            for k in range(bursts):
                sent_at.append(time.monotonic_ns())
                for i in range(3):
                    tx.sendto(bytes([k, i]), ep.local_address)
                time.sleep(0.004)

    try:
        await asyncio.to_thread(send)
        for _ in range(100):
            if len(got) >= len(expected):
                break
            await asyncio.sleep(0.01)
        stats = ep.poll.stats()
        assert sorted(got) == expected
        # 4 ms, give or take a busy machine's sleeps: the sender's own gaps are the measure of what it sent
        gaps = sorted(b - a for a, b in zip(sent_at, sent_at[1:]))
        assert 3_000 * US <= stats["period_ns"] <= max(12_000 * US, 2 * gaps[len(gaps) // 2]), gaps
        assert 1 <= stats["caught"] <= stats["windows"] and stats["spun_ns"] > 0
    finally:
        ep.close()
    assert ep.poll is None


def test_the_setting() -> None:
    assert parse_arrival_poll("auto") == (AUTO_POLL_LEAD_NS, AUTO_POLL_MAX_PERIOD_NS) == (80 * US, 500 * US)
    assert parse_arrival_poll(" OFF ") is None
    assert parse_arrival_poll("60us") == (60 * US, None) == parse_arrival_poll("60")
    for bad in ("0us", "2ms", "soon"):
        with pytest.raises(ValueError, match="expected"):
            parse_arrival_poll(bad)
    loop = asyncio.new_event_loop()
    try:
        assert ArrivalPoll.create(loop, lambda: False, None) is None
    finally:
        loop.close()


def test_the_lead_follows_the_timer_s_late_wake_ups_and_a_missed_burst_restores_it() -> None:
    """Every LATE_SAMPLES polls the lead becomes the second latest wake-up plus the margin, at most the lead given;
    a burst the reader had instead of the poll sets the full lead back."""
    loop = asyncio.new_event_loop()
    r = _Recorder(loop, 80 * US, None)
    try:
        for late in [30 * US] * (LATE_SAMPLES - 2) + [40 * US, 90 * US]:
            r.poll.woke(late)
        assert r.poll.wake_lead_ns == 40 * US + LEAD_MARGIN_NS  # the second latest (≈ p97), not the outlier
        t = [k * 250 * US + 10**9 for k in range(SAMPLES + 1)]
        r.poll._polling = True
        r.feed(t)  # read in the poll: the adapted lead stays
        r.poll._polling = False
        assert r.set[-1] == t[-1] + 250 * US - (40 * US + LEAD_MARGIN_NS)
        for _ in range(LATE_SAMPLES):
            r.poll.woke(1 * US)
        assert r.poll.wake_lead_ns == 1 * US + LEAD_MARGIN_NS
        for _ in range(LATE_SAMPLES):
            r.poll.woke(500 * US)
        assert r.poll.wake_lead_ns == 80 * US  # never beyond the lead given
        r.poll.woke(1 * US)
        r.poll.wake_lead_ns = 20 * US
        r.feed([t[-1] + 250 * US])  # the reader had this one: the full lead again, the samples restarted
        assert r.poll.wake_lead_ns == 80 * US and r.set[-1] == t[-1] + 500 * US - 80 * US and r.poll._lates == []
        assert r.poll.stats()["lead_ns"] == 80 * US
    finally:
        r.poll.close()
        loop.close()


def test_the_poll_yields_the_cpu_between_empty_reads(monkeypatch) -> None:
    """While it waits for a burst the poll gives its CPU to any process queued on it (``sched_yield`` after each
    empty read): the master, packed on the same CPU, must run to send the very burst the poll waits for
    (docs/performance.md). None after the read that got the burst."""
    yields: list[int] = []
    reads: list[int] = []
    monkeypatch.setattr("os.sched_yield", lambda: yields.append(len(reads)))

    def read() -> bool:
        reads.append(1)
        return len(reads) == 4  # the burst is there at the fourth read

    loop = asyncio.new_event_loop()
    poll = ArrivalPoll(loop, read, 80 * US, None)
    try:
        now = time.monotonic_ns()
        poll._due, poll._until, poll.poll_at_ns = now, now + 10**9, now  # a poll set, due now, ending in 1 s
        poll._on_timer()
        assert len(reads) == 4 and poll.caught == 1 and poll.windows == 1
        assert yields == [1, 2, 3]  # one after each empty read, in between
    finally:
        poll.close()
        loop.close()


def test_auto_stands_down_while_idle_cpus_poll_and_a_lead_given_does_not(monkeypatch) -> None:
    """"auto" (a longest cycle) is armed only while idle CPUs halt: while the kernel holds the CPU wake-up latency
    at 0 (``mlink-sim up --realtime``, or any other holder of it) the timer wakes the worker on time and the poll only
    costs CPU (docs/performance.md). Asked once a second, not per burst. A lead given
    polls anyway."""
    limit = [0]
    asked: list[int] = []

    def wakeup_latency_limit() -> int:
        asked.append(limit[0])
        return limit[0]

    monkeypatch.setattr("mlink_sim.aio.timing.arrival.wakeup_latency_limit", wakeup_latency_limit)
    loop = asyncio.new_event_loop()
    auto = _Recorder(loop, 80 * US, 500 * US)
    lead = _Recorder(loop, 80 * US, None)
    try:
        t = [10**9 + k * 250 * US for k in range(SAMPLES + 1)]
        auto.feed(t)
        lead.feed(t)
        assert auto.poll.period_ns == 250 * US and not auto.poll.armed and auto.set == []
        assert auto.poll.stats()["idle_cpus_poll"] == 1
        assert lead.poll.armed and lead.poll.stats()["idle_cpus_poll"] == 0
        assert len(asked) == 1  # the lead given never asks; "auto" once so far
        limit[0] = 2_000_000_000  # the request withdrawn: the CPUs halt again
        more = [t[-1] + k * 250 * US for k in range(1, 400)]  # < 1 s later: not asked yet
        auto.feed(more)
        assert len(asked) == 1 and not auto.poll.armed
        auto.feed([more[-1] + QOS_RECHECK_NS])
        assert len(asked) == 2 and auto.poll.armed and auto.poll.stats()["idle_cpus_poll"] == 0
    finally:
        auto.poll.close()
        lead.poll.close()
        loop.close()
