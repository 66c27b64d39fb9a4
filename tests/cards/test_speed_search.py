"""Speed search through the cards: the b3 / n101-n102 parameters over PRM_RD (SI-T3 Table 8, SI-ET3 PRM_RD,
SI-T/V7 §7.1), and what a master sees of a coasting motor in the INV_CTL response (SI-T3 STATUS field bit 6
0SP, Table 18 SEL_MON code 1 = U1-05 motor speed; SI-T3 Table 26 code 07H oC)."""

from __future__ import annotations

from mlink_sim.wire import M2Status, ml2, ml3

from .helpers import Master, alarm, cmd_alm, station
from .test_commands import _up, _word

# run and reference from the option, coast to stop, 1 s accel/decel over E1-04 (60 Hz)
RUN = ("b1-01=3", "b1-02=3", "b1-03=1", "C1-01=1.0", "C1-02=1.0")
SEL_MON = 0x41  # SEL_MON1 = 1 (U1-05 motor speed), SEL_MON2 = 4 (U1-01), the master's default


def test_si_t3_prm_rd_b3_01_and_b3_17_to_b3_19_defaults() -> None:
    """MEMOBUS registers 0191H (b3-01) and 01F0H-01F2H (b3-17, b3-18, b3-19; A1000 TM, b3 table)."""
    m = Master(station("si-t3"))
    assert m.send(ml2.PrmRd(0x0191, 2)).message.body.parameter == _word(0)
    r = m.send(ml2.PrmRd(0x01F0, 6))
    assert r.message.body.parameter == bytes((150, 0, 10, 0, 3, 0, 0, 0))
    assert m.send(ml2.PrmRd(0x01C0, 2)).message.body.parameter == _word(0)  # b3-24 Current Detection


def test_si_et3_prm_rd_b3_01_and_param_override() -> None:
    m = _up("si-et3")
    r = m.send(ml3.PrmRd(0x0191, 2))
    assert r.message.body.parameter == _word(0) and cmd_alm(r) == 0
    m1 = _up("si-et3", "b3-01=1")
    r = m1.send(ml3.PrmRd(0x0191, 2))
    assert r.message.body.parameter == _word(1) and cmd_alm(r) == 0
    assert m1.st.drive.settings.search.at_start


def test_si_t_v7_prm_rd_n101_n102_defaults() -> None:
    m = _up("si-t-v7")
    r = m.send(ml2.InvCtl(), ml2.PrmRd(0x0165, 4))  # n101, n102 at 0100H + n
    assert r.message.sub.parameter == bytes((20, 0, 150, 0, 0, 0, 0, 0))


def _coast_then_run(*params: str) -> tuple[Master, list[tuple[int, int, int]]]:
    """Run at 30 Hz for 1.5 s, RUN off (coast, b1-03 = 1) for 0.1 s, RUN again; (STATUS, MON1, ALARM) per cycle
    of the coast and of the 3 s after the new run command."""
    m = _up("si-t3", *RUN, *params)
    for _ in range(1500):
        m.send(ml2.InvCtl(signals=1, speed_ref=3000, sel_mon=SEL_MON))
    seen = []
    for _ in range(100):
        r = m.send(ml2.InvCtl(signals=0, speed_ref=3000, sel_mon=SEL_MON))
        seen.append((r.message.status, r.message.body.mon1, alarm(r)))
    for _ in range(3000):
        r = m.send(ml2.InvCtl(signals=1, speed_ref=3000, sel_mon=SEL_MON))
        seen.append((r.message.status, r.message.body.mon1, alarm(r)))
    return m, seen


def test_coasting_motor_shows_0sp_but_u1_05_turns() -> None:
    """0SP follows the output frequency (the A1000's "during zero speed" in V/f), so a coasting motor reads
    0SP = 1 while U1-05 (SEL_MON 1) still gives its speed: U1-05 is what tells a master that the motor turns."""
    _, seen = _coast_then_run()
    status, mon1, _ = seen[50]
    assert status & M2Status.ZSP and not status & M2Status.BB_OFF
    assert 1500 < mon1 < 3000  # 0.01 Hz (o1-03 = 0): slowing down from 30 Hz under its load


def test_si_t3_run_into_coasting_motor_without_speed_search_trips_oc() -> None:
    m, seen = _coast_then_run()
    assert any(a == 0x07 and s & M2Status.ALM for s, _, a in seen[100:])  # SI-T3 Table 26: 07H oC
    assert m.st.drive.drive.status.faulted


def test_si_t3_run_into_coasting_motor_with_b3_01_resumes_without_fault() -> None:
    m, seen = _coast_then_run("b3-01=1")
    assert not any(s & M2Status.ALM or a for s, _, a in seen)
    status, mon1, _ = seen[-1]
    assert status & M2Status.AGREE and status & M2Status.RUNX and not status & M2Status.ZSP
    assert m.last.message.body.output_freq == 3000 and 2900 < mon1 <= 3000
