"""``[deploy]`` and a station's ``node``/``cpus``: the placement of ``compose --stack``/``--k8s`` is checked with
the rest of the config, each mistake one message naming the field (docs/configuration.md, "[deploy]")."""

from __future__ import annotations

import pytest

from mlink_sim.config import ConfigError, parse_config

BASE = """
[network]
name = "p"
transmission_cycle = "2ms"

[[station]]
address = 0x21
card = "si-t3"
{station21}

[[station]]
address = 0x22
card = "si-t3"
"""


def _config(deploy: str = "", station21: str = ""):
    return parse_config(BASE.format(station21=station21) + deploy, "p.toml")


def test_no_placement_by_default():
    config = _config()
    assert config.deploy.label == "mlink.node" and config.deploy.worker == [] and config.deploy.master.node is None
    assert config.station[0].node is None and config.station[0].cpus is None


def test_a_full_placement_reads_back():
    config = _config('[deploy]\nlabel = "example.com/rack"\nnodes = { a = "192.0.2.1", b = "b.example" }\n'
                     'master = { node = "a", cpus = [3] }\n[[deploy.worker]]\nstations = ["21H"]\nnode = "b"\n'
                     'cpus = "1,0"\n', station21="")
    assert config.deploy.master.cpus == "3" and config.deploy.worker[0].stations == [0x21]
    assert config.deploy.worker[0].cpus == "0,1"


@pytest.mark.parametrize(
    ("deploy", "station21", "message"),
    [
        ("", 'node = "b"', "deploy.master.node: stations run on node b; place the master too"),
        ('[deploy]\nmaster = { node = "a" }\n', 'node = "b"', "deploy.nodes: no address for node b, a"),
        ('[deploy]\nnodes = { a = "1.2.3.4", b = "5.6.7.8" }\nmaster = { node = "a" }\n', 'node = "b b"',
         "station[0].node: expected a node label value"),
        ("", 'cpus = "x"', "station[0].cpus: expected CPU numbers separated by commas"),
        ("", "cpus = true", "station[0].cpus: expected CPU numbers such as"),
        ('[deploy]\nlabel = "no spaces please"\n', "", "deploy.label: expected a node label key"),
        ('[deploy]\nnodes = { a = "not an address" }\n', "", "deploy.nodes: a: expected a host name or IP address"),
        ('[[deploy.worker]]\nstations = [0x29]\n', "", "deploy.worker[0].stations: 29H is not a station"),
        ('[[deploy.worker]]\nstations = [0x21]\n[[deploy.worker]]\nstations = [0x21]\n', "",
         "deploy.worker[1].stations: 21H is already served by deploy.worker[0]"),
        ('[[deploy.worker]]\nstations = []\n', "", "deploy.worker[0].stations"),
        ('[[deploy.worker]]\nstations = [0x21]\n', 'cpus = "0"', "station 21H: its node and cpus are those of "
                                                                 "deploy.worker[0]"),
        ('[deploy]\nmaster = { host = "a" }\n', "", "deploy.master.host"),
    ],
)
def test_placement_mistakes_name_the_field(deploy, station21, message):
    with pytest.raises(ConfigError) as err:
        _config(deploy, station21)
    assert message in str(err.value)


def test_stations_beside_an_unplaced_master_need_no_addresses():
    config = _config('[[deploy.worker]]\nstations = [0x21, 0x22]\ncpus = "0"\n')
    assert config.deploy.worker[0].node is None
