"""The fixture's fault injection (docs/faults.md, "From a test"): ``mlink_network.impair(0x21, loss=0.1,
for_=2.0)`` and ``heal()``, on the virtual clock (the real-clock host serves the same two methods; tests/e2e)."""

from __future__ import annotations

import pytest

from mlink_sim.operations import OpError


@pytest.mark.mlink_network("configs/faults-network.toml", clock="virtual", seed=2)
def test_impair_then_heal_a_station(mlink_network):
    net = mlink_network
    reply = net.impair(0x21, loss=0.1, for_=2.0)  # every tenth datagram, both ways, for two simulated seconds
    assert reply["impairment"] == {"loss": 0.1, "for": "2000000000ns"} and reply["describe"] == "loss 10%, for 2s"
    assert reply["name"] == "loss-21H-1"
    net.wait(1.0)
    injected = net.metrics.report["station"]["0x21"]["injected"]
    assert injected["drops"] > 0
    net.check("station[0x21].injected.drops > 0", "station[0x21].reception_failures > 0",
              "station[0x22].injected.drops == 0")
    assert net.heal() == 1  # loss-21H-1, both its directions
    drops = net.metrics.report["station"]["0x21"]["injected"]["drops"]
    net.wait(0.5)
    assert net.metrics.report["station"]["0x21"]["injected"]["drops"] == drops  # healed: nothing more


@pytest.mark.mlink_network("configs/faults-network.toml", clock="virtual")
def test_every_station_and_the_text_form(mlink_network):
    mlink_network.impair("all", "corrupt=2%,direction=to-station,for=0.5s")
    mlink_network.wait(1.0)
    for station in ("0x21", "0x22", "0x23"):
        assert mlink_network.metrics.report["station"][station]["injected"]["corruptions"] > 0
    with pytest.raises(OpError, match="loss: a probability") as err:
        mlink_network.impair(0x21, loss=2)
    assert err.value.kind == "bad_request"
    with pytest.raises(OpError, match="station: expected a station address"):
        mlink_network.impair("nowhere", loss=0.1)


@pytest.mark.mlink_network("configs/faults-network.toml", clock="virtual")
def test_healing_one_station_of_an_every_station_impairment(mlink_network):
    net = mlink_network
    net.impair("all", "delay=100us,direction=to-station")
    assert net.heal(0x21) == 1  # 21H's own share of it
    net.wait(0.2)
    injected = {k: v["injected"]["delays"] for k, v in net.metrics.report["station"].items()}
    assert injected["0x21"] == 0 and injected["0x22"] > 0 and injected["0x23"] > 0


@pytest.mark.mlink_network("configs/faults-network.toml", clock="virtual", seed=3)
def test_named_impairments_stack_are_listed_with_what_each_injected_and_heal_one_by_one(mlink_network):
    """docs/faults.md, "Names": a named impairment stacks beside the station's others; faults lists each with what
    it injected; heal NAME ends that one only; heal of the station ends what is left, faults included."""
    net = mlink_network
    assert net.impair(0x21, "loss=5%", name="lossy")["name"] == "lossy"
    assert net.impair(0x21, "delay=300us,direction=to-station")["name"] == "delay-21H-1"
    silence = net.fault(0x22, "silence,for=5s")
    assert silence["name"] == "silence-22H-1"
    net.wait(1.0)
    listed = {f["name"]: f for f in net.faults()["faults"]}
    assert set(listed) == {"lossy", "delay-21H-1", "silence-22H-1"}
    assert listed["lossy"]["kind"] == "impairment" and listed["lossy"]["given"] is True
    assert listed["lossy"]["injected"]["drops"] > 0 and "delays" not in listed["lossy"]["injected"]
    assert listed["delay-21H-1"]["injected"]["delays"] > 0 and listed["delay-21H-1"]["direction"] == "to-station"
    assert listed["silence-22H-1"]["kind"] == "fault" and listed["silence-22H-1"]["stations"] == ["0x22"]
    assert listed["silence-22H-1"]["injected"]["silences"] > 0 and 3.5 < listed["silence-22H-1"]["left_s"] <= 4.0
    assert net.heal(name="lossy") == 1
    assert [f["name"] for f in net.faults()["faults"]] == ["delay-21H-1", "silence-22H-1"]
    assert net.heal(name="silence-22H-1") == 1  # the silence ends now, 4 s early: its recovery counts from here
    net.wait(0.3)
    episode = net.fault_episode(0x22)
    assert episode.end_ns is not None and episode.recovery_ns is not None
    assert [f["name"] for f in net.faults()["faults"]] == ["delay-21H-1"]
    assert net.heal(0x21) == 1 and net.faults()["faults"] == []
    with pytest.raises(OpError, match="no impairment or fault is called 'lossy'"):
        net.heal(name="lossy")
