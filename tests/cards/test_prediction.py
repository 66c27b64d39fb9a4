"""A card's answer made ahead (mlink_sim.cards.prediction, docs/cards.md "The answer made ahead"): whenever a
prediction answers a command, the card's own ``receive`` of that command at that time answers the same bytes."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mlink_sim import _accel
from mlink_sim.cards.prediction import Prediction
from mlink_sim.drive.drive import QUIET_FOREVER
from mlink_sim.wire import Kind, decode, encode, ml2, ml3
from mlink_sim.wire.frame import with_fcs

from .helpers import MASTER, MS, Master, station
from .test_fast_path import PARAMS, step

CARDS = [("si-t3", 32), ("si-t3", 17), ("si-t-v7", 32), ("si-t-v7", 17), ("si-et3", 64), ("si-et3", 32)]


class Checked:
    """A master and its card, each command offered to the card's last prediction first, as a slave worker does
    (mlink_sim.aio.slave.bus): a predicted answer must be the card's own; a poll between commands drops the prediction."""

    def __init__(self, card: str, size: int) -> None:
        self.m = Master(station(card, params=PARAMS[card], frame_size=size))
        self.m.bring_up()
        self.pred: Prediction | None = None
        self.hits = self.offered = 0

    def deliver(self, datagram: bytes, source: Any = None) -> bytes | None:
        m = self.m
        source = m.source if source is None else source
        predicted = None if self.pred is None else self.pred.answer_to(datagram, source, m.now)
        real = m.st.receive(datagram, source, m.now)
        self.offered += 1
        if predicted is not None:
            self.hits += 1
            assert real == predicted
        self.pred = m.st.prediction(m.now)
        if real is not None and source == m.source:
            m.slave_echo = decode(real, kind=Kind.RESPONSE).message.rwdt & 0xF
        return real

    def poll(self, now: int) -> None:
        self.m.st.poll(now)
        self.pred = None

    def deliver_backlog(self, datagrams: list[bytes]) -> list[bytes | None]:
        """*datagrams* read at once (a backlog, all at ``m.now``), as the bus serves them: the prediction answers as
        many as it carries, moved on from each to the next; then the card takes them all in order, and each answer
        made ahead must be the card's own."""
        m = self.m
        pred, predicted = self.pred, []
        for datagram in datagrams:
            answer = None if pred is None else pred.answer_to(datagram, m.source, m.now)
            if answer is None:
                break
            predicted.append(answer)
            if not pred.advance():  # type: ignore[union-attr]  # not None: it answered
                break
        real = [m.st.receive(datagram, m.source, m.now) for datagram in datagrams]
        assert real[:len(predicted)] == predicted
        self.offered += len(datagrams)
        self.hits += len(predicted)
        self.pred = m.st.prediction(m.now)
        answered = [r for r in real if r is not None]
        if answered:
            m.slave_echo = decode(answered[-1], kind=Kind.RESPONSE).message.rwdt & 0xF
        return real


def _inv_ctl(ml3_link: bool, signals: int, speed: int, sel_mon: int = 0x21, ref: int = 0) -> Any:
    if ml3_link:
        return ml3.InvCtl(signals | (signals << 8 & 0xFF0000), 0, speed, 0, 0, sel_mon, ref, 0)
    return ml2.InvCtl(signals, speed, 0, 0, sel_mon, ref, 0)


@pytest.mark.parametrize("card, size", CARDS)
@settings(max_examples=40, deadline=None)
@given(steps=st.lists(step, min_size=1, max_size=60), repeat=st.integers(1, 30))
def test_a_predicted_answer_is_the_cards_own(card: str, size: int, steps: list[dict], repeat: int) -> None:
    """Random INV_CTL commands (skipped cycles, wrong WDTs, ALM_CLR, sub-commands), each sent *repeat* times so that
    steady runs form: every answer a prediction gave equals the one the card gives the same command."""
    c = Checked(card, size)
    m = c.m
    for s in steps:
        for _ in range(repeat):
            m.tick(s["skip"] + 1)
            if m.ml3:
                body: Any = ml3.InvCtl(s["signals"] | (s["signals"] << 8 & 0xFF0000), 0, s["speed"], s["torque"],
                                       s["sel_ref"], s["sel_mon"], *s["refs"])
                sub = ml3.PrmRd(0x0200, 2) if s["sub"] == "prm_rd" and size == 64 else None
                kw: dict[str, Any] = {"cmd_ctrl": s["ctrl"]}
            else:
                body = ml2.InvCtl(s["signals"], s["speed"], s["torque"], s["sel_ref"], s["sel_mon"], *s["refs"])
                sub = ml2.PrmRd(0x0200, 2) if s["sub"] == "prm_rd" and size == 32 else None
                kw = {}
            c.deliver(encode(m.command(body, sub, wdt=0x05 if s["wdt_bad"] else None, **kw)))
            if s["skip"] == 2:
                c.poll(m.now + MS // 2)


@pytest.mark.parametrize("card, size", CARDS)
@settings(max_examples=25, deadline=None)
@given(steps=st.lists(step, min_size=1, max_size=40), repeat=st.integers(1, 20))
def test_the_datagram_a_prediction_checked_is_taken_as_a_copy_of_it_is(card: str, size: int, steps: list[dict],
                                                                        repeat: int) -> None:
    """A card takes the very datagram its prediction was checked against without comparing it with its last
    command again (``Station._steady_delta`` reuses the check's result). Two cards, one offered each command's
    object through its prediction first (as a worker does), the other a fresh copy of it and no prediction: the
    same answers, and the same counters and state at the end."""
    c = Checked(card, size)
    m = c.m
    other = Master(station(card, params=PARAMS[card], frame_size=size))
    other.bring_up()  # the same commands at the same times as c's card had
    twin = other.st
    rest = {"signals": 0, "speed": 0, "sel_mon": 0x21, "refs": (0, 0), "skip": 0, "wdt_bad": False}
    for s in [rest] * 20 + steps:  # a steady start: some answers are made ahead whatever the steps
        body = _inv_ctl(m.ml3, s["signals"], s["speed"], s["sel_mon"], s["refs"][0])
        for _ in range(repeat):
            m.tick(s["skip"] + 1)
            if s["skip"] == 2:  # a poll between two commands: the next one is not offered to the prediction
                c.poll(m.now - MS // 2)
                twin.poll(m.now - MS // 2)
            dg = encode(m.command(body, wdt=0x05 if s["wdt_bad"] else None))
            assert c.deliver(dg) == twin.receive(bytes(bytearray(dg)), m.source, m.now)  # bytes(dg) is dg itself
        run = []  # and a backlog: the prediction checks (and moves on through) several before the card takes any
        for _ in range(3):
            m.tick()
            run.append(encode(m.command(body)))
        assert c.deliver_backlog(run) == [twin.receive(bytes(bytearray(dg)), m.source, m.now) for dg in run]
    assert c.hits >= 15
    assert twin.counters.as_dict() == m.st.counters.as_dict()
    assert twin.snapshot() == m.st.snapshot()


@pytest.mark.parametrize("card, size", CARDS)
def test_the_connected_master_is_its_address_not_the_object_that_carried_it(card: str, size: int) -> None:
    """docs/cards.md "Who may change a station": a station is owned by the source address (IP and port) whose
    CONNECT it accepted (SI-T3 CONNECT "Establish Connection", SI-ET3 Table 9). The card and its prediction test the
    source by identity first (a worker hands one source's datagrams the same object); an equal address in another
    object is still that master: answered, ahead as for the same object, never counted foreign."""
    c, body = _at_rest(card, size)
    m = c.m
    m.source = (m.source[0], m.source[1])  # the same address, a new tuple
    assert m.source == MASTER and m.source is not MASTER
    hits = c.hits
    for _ in range(30):
        m.tick()
        assert c.deliver(encode(m.command(body))) is not None
    assert c.hits - hits >= 25 and m.st.counters.foreign_source == 0
    assert m.st.snapshot().connected_source == MASTER


@pytest.mark.parametrize("card, size", CARDS)
@settings(max_examples=25, deadline=None)
@given(steps=st.lists(step, min_size=1, max_size=30), repeat=st.integers(1, 12), backlog=st.integers(2, 8))
def test_a_prediction_moved_on_through_a_backlog_answers_as_the_card_does(card: str, size: int, steps: list[dict],
                                                                          repeat: int, backlog: int) -> None:
    """A backlog (several commands for the station in one read, ``Prediction.advance``): random INV_CTL commands,
    runs of *backlog* of them read at once; every answer the moved-on prediction gives is the card's own answer to
    that command, taken after the ones before it."""
    c = Checked(card, size)
    m = c.m
    for s in steps:
        body = _inv_ctl(m.ml3, s["signals"], s["speed"], s["sel_mon"])
        for _ in range(repeat):
            run = []
            for _ in range(backlog):
                m.tick(s["skip"] + 1)
                run.append(encode(m.command(body, wdt=0x05 if s["wdt_bad"] else None)))
            c.deliver_backlog(run)


def _at_rest(card: str, size: int) -> tuple[Checked, Any]:
    """A card brought up and given 50 cycles of one command at rest (stopped, speed 0): it predicts; and that
    command's body."""
    c = Checked(card, size)
    m = c.m
    body = _inv_ctl(m.ml3, 0, 0)
    for _ in range(50):
        m.tick()
        c.deliver(encode(m.command(body)))
    return c, body


@pytest.mark.parametrize("card, size", CARDS)
def test_a_steady_backlog_is_answered_ahead_in_full(card: str, size: int) -> None:
    """At rest, a read holding the next 8 commands is answered ahead in full, and the card's answers to them, taken
    afterwards, are those (one a cycle on, the cycles, WDT and RWDT counts each advanced)."""
    c, body = _at_rest(card, size)
    m = c.m
    assert c.pred is not None
    hits = c.hits
    run = []
    for _ in range(8):
        m.tick()
        run.append(encode(m.command(body)))
    answers = c.deliver_backlog(run)
    assert c.hits - hits == 8
    frames = [decode(a, kind=Kind.RESPONSE) for a in answers if a is not None]
    assert [f.cycle for f in frames] == [decode(d, kind=Kind.COMMAND).cycle for d in run]
    rwdt = [f.message.rwdt for f in frames]
    assert [(r & 0xF) for r in rwdt] == [((rwdt[0] & 0xF) + i) & 0xF for i in range(8)]
    assert [(r >> 4) for r in rwdt] == [((rwdt[0] >> 4) + i) & 0xF for i in range(8)]


@pytest.mark.parametrize("card, size", CARDS)
def test_the_steady_state_is_answered_ahead_and_every_change_is_not(card: str, size: int) -> None:
    """Long runs of one command are answered from the prediction; a corrupted FCS, a wrong WDT, a skipped cycle,
    another station's byte, another source, an ALM_CLR edge, a new command and a poll between two commands are not
    (a late command, after the card's silence deadline and no poll, may be: it is checked like every other), and
    the card's answers stay its own throughout: a ramp, a steady run, a stop, and forward and reverse at once (EF
    after 0.5 s, A1000 / VS-606V7)."""
    c = Checked(card, size)
    m = c.m
    fwd, both = 1, 3
    plan: list[tuple[int, int, str]] = [(fwd, 3000, "run")] * 400
    events = ["bad_fcs", "bad_wdt", "skip", "station", "other_source", "poll"] + ["clear"] * m.ml3
    for event in events[:5] + ["late"] + events[5:]:
        plan += [(fwd, 3000, event)] + [(fwd, 3000, "run")] * 5
    plan += [(fwd, 6000, "run")] * 300 + [(0, 0, "run")] * 300 + [(both, 3000, "run")] * 800
    misses: dict[str, int] = {}
    for signals, speed, what in plan:
        m.tick(2 if what == "skip" else 1)
        if what == "late":
            m.now += 5 * MS
        if what == "poll":
            c.poll(m.now - MS // 2)
        kw: dict[str, Any] = {"cmd_ctrl": 0x08} if what == "clear" and m.ml3 else {}
        if what == "bad_wdt":
            kw["wdt"] = 0x05
        dg = bytearray(encode(m.command(_inv_ctl(m.ml3, signals, speed), **kw)))
        if what == "bad_fcs":
            dg[-1] ^= 0x10
        elif what == "station":
            dg[3] ^= 0x01
            dg[-2:] = with_fcs(bytes(dg[:-2]))[-2:]
        hits = c.hits
        c.deliver(bytes(dg), ("10.9.9.9", 1) if what == "other_source" else None)
        if what not in ("run", "late"):
            misses[what] = c.hits - hits
    assert misses == dict.fromkeys(misses, 0), misses  # none of the changes was answered ahead
    assert set(misses) == set(events)
    assert c.hits > 0.6 * c.offered, (c.hits, c.offered)  # and most of the steady state was


@pytest.mark.parametrize("card, size", CARDS)
def test_a_command_read_after_the_silence_deadline_is_answered_ahead_unless_a_poll_came_first(card: str,
                                                                                              size: int) -> None:
    """At rest, a command read 5 ms after the one before (a worker held up: the tick reads what queued before it
    polls) is answered ahead, and the card's own answer is the same (no silence counted: no poll came between).
    After a poll past the deadline (silence counted, SI-T3 Table 22), the prediction is gone."""
    c, body = _at_rest(card, size)
    m = c.m
    m.tick()
    m.now += 5 * MS
    hits = c.hits
    c.deliver(encode(m.command(body)))
    assert c.hits == hits + 1 and m.st.counters.reception_failures == 0
    for _ in range(5):
        m.tick()
        c.deliver(encode(m.command(body)))
    m.tick()
    m.now += 5 * MS
    c.poll(m.now - MS // 2)
    hits = c.hits
    c.deliver(encode(m.command(body)))
    assert c.hits == hits and m.st.counters.reception_failures > 0


@pytest.mark.parametrize("card, size", [("si-t3", 17), ("si-et3", 32)])
def test_no_prediction_outside_the_steady_state(card: str, size: int) -> None:
    """Before the connection, after a new command and during a ramp the card offers none; at rest it does, past its
    silence deadline too (silence is counted by a poll, which drops the prediction first)."""
    m = Master(station(card, params=PARAMS[card], frame_size=size))
    assert m.st.prediction(0) is None  # phase 1
    m.bring_up()
    m.send(_inv_ctl(m.ml3, 1, 6000))
    assert m.st.prediction(m.now) is None  # the command just changed
    for _ in range(5):
        m.send(_inv_ctl(m.ml3, 1, 6000))
    assert not m.st.drive.drive.is_steady and m.st.prediction(m.now) is None  # ramping (C1-01)
    for _ in range(3000):  # stop again (C1-02): at rest, steady
        m.send(_inv_ctl(m.ml3, 0, 0))
    pred = m.st.prediction(m.now)
    assert m.st.drive.drive.is_steady and pred is not None
    assert pred.until == QUIET_FOREVER - 1  # at rest nothing timed bounds it; the silence deadline does not
    assert m.st.prediction(m.st.next_deadline() + 10 * MS) is not None


def test_the_drive_is_quiet_until_its_next_event() -> None:
    """Drive.quiet_until: -1 while not steady; its timed event (EF: forward and reverse for 0.5 s) bounds it."""
    m = Master(station("si-et3", params=PARAMS["si-et3"], frame_size=32))
    m.bring_up()
    drive = m.st.drive.drive
    assert drive.is_steady and drive.quiet_until() == QUIET_FOREVER  # at rest, nothing timed
    m.send(_inv_ctl(True, 3, 0))  # forward and reverse at once, speed 0: still at rest, EF ahead
    start = m.now
    m.send(_inv_ctl(True, 3, 0))
    assert drive.is_steady and drive.quiet_until() == start + 500 * MS
    m.send(_inv_ctl(True, 1, 6000))
    assert drive.quiet_until() == -1  # accelerating


@pytest.mark.skipif(_accel.MODE == "compiled", reason="breaks a card's typed attribute, which compiled (mypyc) classes "
                    "refuse; runs in CI's pure pass (MLINK_PURE=1)")
def test_a_card_that_cannot_predict_counts_an_internal_error_and_offers_none() -> None:
    """Station.prediction never raises: a failure in it is the card's internal error, and no prediction."""
    m = Master(station("si-et3", params=PARAMS["si-et3"], frame_size=32))
    m.bring_up()
    for _ in range(5):
        m.send(_inv_ctl(True, 0, 0))
    assert m.st.prediction(m.now) is not None
    m.st._answer = None  # type: ignore[assignment]
    assert m.st.prediction(m.now) is None and m.st.counters.internal_errors == 1


@pytest.mark.parametrize("card, size", [("si-t3", 17), ("si-t-v7", 17)])
def test_an_answer_carrying_a_warning_is_not_repeated_ahead_si_t3_table22(card: str, size: int) -> None:
    """SI-T3 Table 22 / SI-T/V7 Table 7: a single reception failure is warning 96 (STATUS WARNG), reported in one
    answer and then dropped (no reset). Two single gaps in a row give two equal answers with WARNG; the command after
    them, on time, must not be answered ahead with the warning: the card answers it without one."""
    c = Checked(card, size)
    m = c.m
    body = _inv_ctl(False, 0, 0)
    for _ in range(20):
        m.tick()
        c.deliver(encode(m.command(body)))
    for _ in range(2):  # one command lost each time, the next one on time: a single failure, twice
        m.tick(2)
        warned = decode(c.deliver(encode(m.command(body))), kind=Kind.RESPONSE)
        assert warned.message.status & 0x02 and warned.message.alarm == 0x96  # WARNG, ALARM byte: warning 96
    m.tick()
    hits = c.hits
    clean = decode(c.deliver(encode(m.command(body))), kind=Kind.RESPONSE)
    assert not clean.message.status & 0x02 and clean.message.alarm == 0 and c.hits == hits  # dropped; not ahead
