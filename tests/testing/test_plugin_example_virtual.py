"""The example of docs/virtual-time.md: the ``mlink_network`` fixture on the virtual clock. The network runs in
the test's process on simulated time, so the bounds can be exact: nothing depends on how busy the machine is
(the real-clock example is test_plugin_example.py)."""

from __future__ import annotations

import pytest

from mlink_sim.master import ParamRequestError, ParamValue, StationAlarmError

C1_01 = 0x0200  # SI-T3 Tables 8/9: C1-01 acceleration time 1 at register 0200H (0.1 s)


@pytest.mark.mlink_network("configs/quickstart.toml", clock="virtual", seed=1)
def test_quickstart_on_virtual_time(mlink_network):
    net = mlink_network
    assert {v.phase for v in net.views().values()} == {3}

    net.run(0x21, hz=30)  # C1-01 = 2.0 s to E1-04 = 60 Hz: 30 Hz after 1 s
    net.wait(2.0)  # two simulated seconds, computed at once
    assert net.output_hz(0x21) == pytest.approx(30.0, abs=0.05)

    assert net.prm_rd(0x21, C1_01) == 20
    with pytest.raises(StationAlarmError) as err:
        net.prm_rd(0x21, 0x7FFF)  # no such register: A.94 (SI-T3 Table 23)
    assert err.value.code == 0x94

    accel = net.prm_rd(0x21, "C1-01")  # by name: the value in its unit (SI-T3 Tables 8/9, 0.1 s)
    assert isinstance(accel, ParamValue) and accel == 2.0 and accel.unit == "s" and accel.raw == 20
    assert accel.register == C1_01
    with pytest.raises(ParamRequestError) as bad:
        net.prm_wr(0x21, "C1-01", 7000.0)  # beyond C1-01's range: refused before anything is sent
    assert bad.value.station == 0x21 and bad.value.name == "C1-01"

    m = net.metrics
    assert m.report["meta"]["clock"] == "virtual"
    assert 80e-6 <= m.rtt.min and m.rtt.max <= 120e-6  # [network] latency 50 us ± jitter 10 us, each way
    net.check("missed == 0", "missing == 0", "reception_failures == 0", "wdt_errors == 0")


@pytest.mark.mlink_network("configs/quickstart.toml", clock="virtual", timeline=True)
def test_quickstart_timeline_on_virtual_time(mlink_network):
    checks = mlink_network.wait_timeline()
    assert checks and [c for c in checks if not c.ok] == []
