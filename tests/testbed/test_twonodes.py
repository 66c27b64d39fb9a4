"""A config on the two nodes of ``scripts/swarm-testbed --nodes 2`` (mlink_sim.testbed.twonodes): the [deploy] the
testbed writes, a config's own two nodes with their addresses on the link, the ones it refuses, the probe from the
master's node and the RTT check."""

from __future__ import annotations

import json
import re

import pytest

from mlink_sim.config import load_config, parse_config
from mlink_sim.testbed import twonodes
from mlink_sim.testbed.placement import plan
from mlink_sim.testbed.stack import stack_document
from mlink_sim.testbed.twonodes import NODE_A, NODE_B, PlaceError, place, remote_workers, rtt_shows_the_link

from .test_stack import QUICKSTART, TWO_NODES, two_nodes

A, B = "198.19.0.1", "198.19.0.2"


def test_an_unplaced_config_gets_the_master_on_this_host_and_every_station_on_the_second_node():
    text, label, node_a, node_b, options = place(load_config(QUICKSTART), QUICKSTART.read_text("utf-8"), A, B)
    assert (label, node_a, node_b, options) == ("mlink.node", NODE_A, NODE_B, [])
    assert text.startswith(QUICKSTART.read_text("utf-8").rstrip("\n"))  # the config itself, unchanged
    placed = parse_config(text, "placed.toml")
    assert placed.deploy.master.node == NODE_A and placed.deploy.nodes == {NODE_A: A, NODE_B: B}
    doc = stack_document(placed)
    assert list(doc["services"]) == ["worker-0", "worker-1", "worker-2", "master"]  # one process per station
    for name in ("worker-0", "worker-1", "worker-2"):
        service = doc["services"][name]
        assert service["deploy"]["placement"]["constraints"] == [f"node.labels.mlink.node == {NODE_B}"]
        argv = service["command"]
        assert argv[argv.index("--allow-master") + 1] == A  # the master's node, as seen from the second
    master = doc["services"]["master"]["command"]
    assert [master[i + 1] for i, a in enumerate(master) if a == "--endpoint"] == [
        f"0x21={B}:47001", f"0x22={B}:47002", f"0x23={B}:47003"]


def test_a_config_with_two_nodes_keeps_its_placement_at_the_links_addresses():
    text, label, node_a, node_b, options = place(two_nodes(), TWO_NODES, A, B)
    assert text == TWO_NODES and (label, node_a, node_b) == ("mlink.node", "plc", "rack-b")
    assert options == ["--node-address", f"plc={A}", "--node-address", f"rack-b={B}"]


@pytest.mark.parametrize(("extra", "message"), [
    ('\n[deploy]\nlabel = "mlink.node"\n', "places nothing"),
    ('\n[deploy]\nnodes = { a = "1.1.1.1", b = "2.2.2.2", c = "3.3.3.3" }\nmaster = { node = "a" }\n'
     '[[deploy.worker]]\nstations = [0x21]\nnode = "b"\n[[deploy.worker]]\nstations = [0x22]\nnode = "c"\n',
     "2 node(s) besides the master's"),
    ('\n[deploy]\nmaster = { node = "a" }\n', "0 node(s) besides the master's"),
])
def test_configs_these_two_nodes_cannot_run_are_refused(extra, message):
    text = QUICKSTART.read_text("utf-8") + extra
    with pytest.raises(PlaceError, match=re.escape(message)):
        place(parse_config(text, "x.toml"), text, A, B)


def test_the_probe_from_the_masters_node_goes_to_each_station_elsewhere_at_its_nodes_address():
    probes = remote_workers(plan(two_nodes(), 47001))
    assert [p[:4] for p in probes] == [["mlink-health", "192.0.2.2:47001", "--station", "0x21"]]  # 23H is beside it


def test_the_rtt_of_every_station_on_the_second_node_must_be_at_least_twice_the_delay():
    assert twonodes.far_stations(plan(two_nodes(), 47001)) == ["0x21", "0x22"]  # 23H is beside the master
    report = {"station": {"0x21": {"rtt": {"p50": 400_000}}, "0x22": {"rtt": {"p50": 450_000}},
                          "0x23": {"rtt": {"p50": 90_000}}}}  # fmt: skip
    held, sentence = rtt_shows_the_link(report, 200_000, ["0x21", "0x22"])
    assert held and sentence.startswith("RTT p50 21H 400us, 22H 450us: each at least twice")
    report["station"]["0x22"]["rtt"]["p50"] = 399_999
    assert not rtt_shows_the_link(report, 200_000, ["0x21", "0x22"])[0]
    assert rtt_shows_the_link({}, 200_000, ["0x21"]) == (
        False, "the report has no RTT median of station 0x21 (station.0x21.rtt.p50)")
    assert not rtt_shows_the_link(report, 200_000, [])[0]


def test_the_command_line(tmp_path, capsys):
    out = tmp_path / "placed.toml"
    assert twonodes.main(["place", str(QUICKSTART), str(out), "--prefix", "mlsw42"]) == 0
    assert "node_a=node-a\nnode_b=node-b\n" in capsys.readouterr().out and "[deploy]" in out.read_text("utf-8")
    report = tmp_path / "report.json"
    report.write_text(json.dumps({"station": {f"0x{a:02x}": {"rtt": {"p50": 100_000}} for a in (0x21, 0x22, 0x23)}}),
                      encoding="utf-8")
    assert twonodes.main(["check", str(report), str(out), "--delay", "200us"]) == 1
    assert "not each at least twice the link's delay (200us each way)" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[network]\n", encoding="utf-8")
    assert twonodes.main(["place", str(bad), str(out), "--prefix", "mlsw42"]) == 2


def test_the_probe_goes_to_the_links_address_of_a_placed_config(tmp_path, monkeypatch, capsys):
    path = tmp_path / "two.toml"
    path.write_text(TWO_NODES, encoding="utf-8")
    sent = []
    monkeypatch.setattr(twonodes.health, "main", lambda argv: sent.append(argv[0]) or 0)
    assert twonodes.main(["probe", str(path), "--port", "47001", "--node-address", f"rack-b={B}"]) == 0
    assert sent == [f"{B}:47001"]
