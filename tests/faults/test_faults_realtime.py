"""Faults on the real-time clock (``mlink-sim up``'s processes, through the plugin): the master-side stage in the
master's process, a drive fault through the slave worker's control endpoint (docs/faults.md)."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.e2e


@pytest.mark.mlink_network("faults-drive")
def test_faults_reach_the_master_stage_and_the_slave_workers_drive(mlink_network):
    net = mlink_network
    net.run(0x22, hz=30)
    net.wait_until(lambda: net.output_hz(0x22) > 29.5, timeout=10)
    net.mains_loss(0x22, for_=0.2)  # {"op": "plant"} to the worker hosting 0x22, released 200 ms later
    net.wait_until(lambda: net.view(0x22).alarm_name == "UV1", timeout=5)
    net.skip_cycles(0x21, count=2)  # E6, cleared by the master (SI-T3 Tables 22/23)
    net.wait_until(lambda: (ep := net.fault_episode(0x21)) is not None and ep.recovery_ns is not None, timeout=5)
    net.set_control(0x22, forward=False, fault_reset=True)
    net.wait_until(lambda: (ep := net.fault_episode(0x22)) is not None and ep.recovery_ns is not None, timeout=5)
    net.check("station[0x21].injected.skips == 2", "station[0x22].injected.drive_faults == 1",
              "station[0x21].recovery.count >= 1", "station[0x22].unrecovered == 0")
