"""Watchdog (docs/cards.md convention) and reception failures: SI-T3 Tables 22–24, SI-T/V7 Tables 7–9, SI-ET3
COMM_ALM, bUS after F6-26 (SI-T3 Table 4 / SI-ET3 Table 7)."""

from __future__ import annotations

from mlink_sim.wire import CommAlm, M2Alarm, M2Status, encode, ml2, ml3

from .helpers import MS, Master, alarm, comm_alm, station

A = ("b1-01=3", "b1-02=3")


def _running(card: str, *params: str) -> Master:
    m = Master(station(card, params=A + params))
    m.bring_up()
    body = ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000) if m.ml3 else ml2.InvCtl(signals=1, speed_ref=3000)
    for _ in range(500):
        m.send(body)
    assert m.st.snapshot().drive.running
    return m


def test_rwdt_convention() -> None:
    """RWDT bits 0–3: the slave's count, +1 per response; bits 4–7: the master's count echoed."""
    m = Master(station("si-t3"))
    r1 = m.nop()
    r2 = m.nop()
    assert (r2.message.rwdt & 0xF) == ((r1.message.rwdt + 1) & 0xF)
    assert r2.message.rwdt >> 4 == m.count & 0xF


def test_si_t3_table_23_24_wdt_error_e5_phase_3_to_2() -> None:
    """SI-T3 Table 23 E5 "MECHATROLINK-II WDT Error"; phase 3 -> 2; the drive faults E5 per F6-25 (1 = coast)."""
    m = _running("si-t3")
    r = m.send(ml2.InvCtl(signals=1, speed_ref=3000), wdt=((m.count + 5) & 0xF) << 4)
    assert alarm(r) == M2Alarm.WDT_ERROR and r.message.status & M2Status.ALM
    assert m.st.phase == 2 and m.st.counters.wdt_errors == 1
    assert m.st.snapshot().drive.fault == "E5"
    assert m.st.snapshot().leds["ERR"] == "on"
    # phase 2 does not check: a stuck count is no error now
    r = m.send(ml2.InvCtl(signals=0), wdt=0)
    assert m.st.counters.wdt_errors == 1


def test_wdt_alarm_only_per_f6_25() -> None:
    m = _running("si-t3", "F6-25=3")
    m.send(ml2.InvCtl(signals=1, speed_ref=3000), wdt=0x00 if m.count & 0xF != 15 else 0x50)
    snap = m.st.snapshot()
    assert snap.drive.fault is None and "E5" in snap.drive.minors and snap.drive.running


def test_si_et3_wdt_error_comm_alm_c() -> None:
    m = _running("si-et3")
    r = m.send(ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000), wdt=((m.count + 3) & 0xF) << 4)
    assert comm_alm(r) == CommAlm.WDT_ERROR and m.st.phase == 2
    assert m.st.snapshot().drive.fault == "E5"
    assert m.st.snapshot().led_colors["R/E"] == "red"


def test_wdt_checked_only_after_sync_set() -> None:
    m = Master(station("si-et3"))
    m.connect(sync=False)
    m.nop(wdt=0x70)
    m.nop(wdt=0x70)
    assert m.st.counters.wdt_errors == 0
    m.sync_set()
    r = m.nop()
    assert comm_alm(r) == 0 and m.st.counters.wdt_errors == 0
    r = m.nop(wdt=m.last.message.wdt if False else ((m.count + 1 + 4) & 0xF) << 4)
    assert comm_alm(r) == CommAlm.WDT_ERROR


def test_lost_command_is_a_reception_failure_not_a_wdt_error() -> None:
    m = _running("si-t3")
    m.tick()  # one command lost
    r = m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    assert alarm(r) == M2Alarm.COMM_WARNING and m.st.counters.wdt_errors == 0 and m.st.phase == 3


def test_si_t3_table_22_first_failure_96_then_e6() -> None:
    """Table 22: phase 2/3 first reception failure 96 (warning), second consecutive E6 (alarm); phase 3 -> 2."""
    m = _running("si-t3", "F6-26=10")
    m.tick()
    r = m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    assert alarm(r) == M2Alarm.COMM_WARNING and r.message.status & M2Status.WARNG
    assert not r.message.status & M2Status.ALM
    r = m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    assert alarm(r) == 0  # a communications warning needs no reset (Table 20)
    m.tick(2)  # two consecutive commands lost
    r = m.send(ml2.InvCtl(signals=1, speed_ref=3000))
    assert alarm(r) == M2Alarm.COMM_ERROR and r.message.status & M2Status.ALM
    assert m.st.phase == 2
    assert alarm(m.send(ml2.InvCtl(signals=1, speed_ref=3000))) == M2Alarm.COMM_ERROR  # held until ALM_CLR
    assert alarm(m.send(ml2.AlmClr(0))) == 0
    assert m.st.counters.reception_failures == 3


def test_v7_tables_7_8_9_reception_failures() -> None:
    """V7 Table 7: first failure 96, consecutive E6; Table 8 codes; Table 9 "Communications failure"."""
    m = Master(station("si-t-v7", params=("n003=3", "n004=9")))
    m.bring_up()
    m.tick()
    assert alarm(m.nop()) == M2Alarm.COMM_WARNING
    m.tick(2)
    assert alarm(m.nop()) == M2Alarm.COMM_ERROR
    assert m.st.snapshot().drive.fault == "bUS"  # notified to the inverter at once: BUS (Table 10 E6H)


def test_silence_96_then_e6_then_bus_after_f6_26() -> None:
    """SI-T3 Tables 22/23: silence – no valid command for longer than the communication cycle plus the tolerance
    (1 ms cycle: max(1 ms, 2 ms) = 2 ms) – is a reception failure: the first warning 96, the next E6. F6-26 = 2:
    the second communication alarm faults bUS, stop per F6-01 (coast)."""
    m = _running("si-t3")
    st = m.st
    last = m.now
    assert st.next_deadline() == last + 3 * MS
    st.poll(last + 3 * MS - 1)
    assert st.counters.reception_failures == 0
    st.poll(last + 3 * MS)  # first failure: warning 96 (shown in the next response)
    assert st.counters.reception_failures == 1 and st.phase == 3
    st.poll(last + 4 * MS)  # second consecutive: E6, phase 2, bUS alarm 1 of 2
    assert st.phase == 2 and st.snapshot().alarm_code == M2Alarm.COMM_ERROR
    assert st.snapshot().drive.fault is None
    st.poll(last + 5 * MS)  # third: bUS alarm 2 of 2 -> drive fault bUS, coast (F6-01 = 1)
    snap = st.snapshot()
    assert snap.drive.fault == "bUS" and st.counters.bus_alarms == 2
    assert snap.connected_source is None  # connection lost: the lock is released
    st.poll(last + 1000 * MS)
    assert not st.snapshot().drive.running


def test_bus_not_detected_without_run_or_reference_from_the_option() -> None:
    m = Master(station("si-t3"))  # b1-01 = 1, b1-02 = 1
    m.bring_up()
    m.st.poll(m.now + 50 * MS)
    assert m.st.snapshot().drive.fault is None and m.st.snapshot().alarm_code == M2Alarm.COMM_ERROR


def test_silence_due_is_exactly_when_poll_counts_the_table_22_failure() -> None:
    """The I/O layer reads waiting commands before a poll that would count silence (aio/slave/server.py): silence_due
    must turn true at the same instant as the SI-T3 Table 22 reception failure, and not before."""
    m = _running("si-t3")
    st, last = m.st, m.now
    assert not st.silence_due(last + 3 * MS - 1)
    st.poll(last + 3 * MS - 1)
    assert st.counters.reception_failures == 0
    assert st.silence_due(last + 3 * MS)
    st.poll(last + 3 * MS)
    assert st.counters.reception_failures == 1
    assert not st.silence_due(last + 4 * MS - 1) and st.silence_due(last + 4 * MS)


def test_silence_tolerance_option() -> None:
    from mlink_sim.cards import CardOptions

    m = Master(station("si-t3", options=CardOptions(silence_tolerance_ns=200_000)))
    m.connect()
    assert m.st.next_deadline() == m.now + 1 * MS + 200_000


def test_phase_1_never_notifies() -> None:
    m = Master(station("si-t3"))
    m.nop()
    m.st.poll(m.now + 1000 * MS)
    m.tick(5)
    r = m.nop()
    assert alarm(r) == 0 and m.st.counters.reception_failures == 0
    assert m.st.next_deadline() is None


def test_si_et3_comm_alm_gap_2_then_9() -> None:
    m = _running("si-et3", "F6-26=10")
    m.tick()
    r = m.send(ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000))
    assert comm_alm(r) == CommAlm.NOT_RECEIVED_WARNING and m.st.phase == 3
    m.tick(2)
    r = m.send(ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000))
    assert comm_alm(r) == CommAlm.NOT_RECEIVED and m.st.phase == 2


def test_si_et3_comm_alm_silence_in_phase_3_is_sync_frame_3_then_a() -> None:
    m = _running("si-et3", "F6-26=10")
    m.st.poll(m.now + 3 * MS)  # 1 ms cycle + tolerance max(1 ms, 2 ms)
    assert m.st.snapshot().alarm_code == CommAlm.SYNC_NOT_RECEIVED_WARNING
    m.st.poll(m.now + 4 * MS)
    assert m.st.snapshot().alarm_code == CommAlm.SYNC_NOT_RECEIVED and m.st.phase == 2


def test_si_et3_comm_alm_fcs_1_then_8() -> None:
    """SI-ET3 manual §8, the COMM_ALM code table under "Command Status (CMD_STAT)" (unnumbered): 1 = FCS error
    (warning), 8 = FCS error (alarm). The bad datagrams are plain bytes, so the FCS check runs in full (in C with
    the compiled cores, mlink_sim/wire/_fcsc.c)."""
    m = _running("si-et3", "F6-26=10")
    m.tick()
    bad = bytearray(encode(m.command(ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000))))
    bad[-1] ^= 0xFF
    assert m.st.receive(bytes(bad), m.source, m.now) is None
    assert m.st.counters.dropped_by_reason["BAD_FCS"] == 1 and m.st.counters.fcs_errors == 1
    r = m.send(ml3.InvCtl(invcmd_ctrl=1, speed_ref=3000))
    assert comm_alm(r) == CommAlm.FCS_WARNING  # reported on the next response; the gap is not counted again
    assert m.st.counters.reception_failures == 1
    for _ in range(2):
        m.tick()
        bad = bytearray(encode(m.command(ml3.Nop())))
        bad[20] ^= 0x01
        m.st.receive(bytes(bad), m.source, m.now)
    r = m.send(ml3.Nop())
    assert comm_alm(r) == CommAlm.FCS_ERROR


def test_si_et3_header_cycle_change_is_b() -> None:
    m = _running("si-et3")
    r = m.send(ml3.Nop(), tcycle_ns=2 * MS)
    assert comm_alm(r) == CommAlm.SYNC_INTERVAL_ERROR and m.st.phase == 2


def test_comm_alm_cleared_by_alm_clr_and_by_rising_edge_of_cmd_ctrl_alm_clr() -> None:
    m = _running("si-et3", "F6-26=10")
    m.tick(3)
    assert comm_alm(m.nop()) == CommAlm.NOT_RECEIVED
    assert comm_alm(m.nop()) == CommAlm.NOT_RECEIVED  # latched
    r = m.nop(cmd_ctrl=0x08)
    assert comm_alm(r) == 0 and r.message.stat.alm_clr_cmp
    r = m.nop(cmd_ctrl=0x08)
    assert r.message.stat.alm_clr_cmp  # while the bit stays set
    assert not m.nop().message.stat.alm_clr_cmp
    m.tick(3)
    assert comm_alm(m.nop()) == CommAlm.NOT_RECEIVED
    assert comm_alm(m.send(ml3.AlmClr(0))) == 0


def test_duplicate_cycle_number_is_dropped() -> None:
    m = Master(station("si-t3"))
    m.connect()
    m.nop()
    assert m.nop(step=False) is None
    assert m.st.counters.dropped_by_reason["DUPLICATE"] == 1


def test_v7_table_8_wdt_fault_e5() -> None:
    m = Master(station("si-t-v7"))
    m.bring_up()
    r = m.nop(wdt=((m.count + 7) & 0xF) << 4)
    assert alarm(r) == M2Alarm.WDT_ERROR and m.st.phase == 2
    assert m.st.snapshot().drive.fault == "E5"  # V7 Table 10 E5H "SI-T WDT fault"


def test_si_t3_table_19_20_fault_types_and_reset() -> None:
    """Table 19/20: communications warning (96) – no reset; communications alarm (E6) – reset required, ERR on;
    drive alarm – reset required."""
    m = Master(station("si-t3", params=("F6-26=10",)))
    m.bring_up()
    m.tick()
    assert alarm(m.nop()) == M2Alarm.COMM_WARNING
    assert alarm(m.nop()) == 0 and m.st.snapshot().leds["ERR"] == "off"
    m.tick(2)
    assert alarm(m.nop()) == M2Alarm.COMM_ERROR
    assert alarm(m.nop()) == M2Alarm.COMM_ERROR and m.st.snapshot().leds["ERR"] == "on"
    assert alarm(m.send(ml2.AlmClr(0))) == 0 and m.st.snapshot().leds["ERR"] == "off"
