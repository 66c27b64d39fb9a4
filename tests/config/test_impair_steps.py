"""``do = "impair"`` / ``do = "heal"`` in the timeline, in the full syntax of docs/faults.md, and the messages for bad
values (docs/faults.md): they stop the config from loading, naming the step and the field."""

from __future__ import annotations

import pytest

from mlink_sim.config import ConfigError, parse_config
from mlink_sim.impair import Impairment

BASE = """
[network]
transmission_cycle = "2ms"
[[station]]
address = 0x21
card = "si-t3"
"""

FULL = """
[[timeline]]
at = "1s"
station = 0x21          # or "all" (the default)
do = "impair"
direction = "both"      # "to-station", "to-master" or "both"
loss = 0.05             # probability per datagram
burst = 3               # optional: mean length of a loss burst (Gilbert–Elliott)
delay = "300us"         # added one-way delay
jitter = "200us"        # uniform spread around the delay
duplicate = 0.01
reorder = 0.01
corrupt = 0.01          # bits flipped after the FCS: the receiver sees a bad FCS
for = "2s"              # then it ends; without it, it lasts until `do = "heal"`

[[timeline]]
at = "2s"
do = "heal"
"""


def test_the_full_syntax_loads() -> None:
    config = parse_config(BASE + FULL)
    impair, heal = config.timeline
    assert impair.impairment == Impairment(direction="both", loss=0.05, burst=3, delay=300_000, jitter=200_000,
                                           duplicate=0.01, reorder=0.01, corrupt=0.01, for_ns=2_000_000_000)
    assert heal.do == "heal" and heal.station == "all"
    assert "loss 5% (bursts of 3), delay 300us ± 200us" in impair.describe
    assert config.run_length_ns == 3_000_000_000


def test_defaults_percentages_and_the_run_direction_unchanged() -> None:
    config = parse_config(BASE + '[[timeline]]\nat = "1s"\ndo = "impair"\nloss = "5%"\n'
                          '[[timeline]]\nat = "2s"\ndo = "run"\nhz = 10\n')
    impair, run = config.timeline
    assert impair.direction == "both" and impair.impairment.loss == 0.05 and impair.impairment.for_ns is None
    assert run.direction == "forward"


@pytest.mark.parametrize(("step", "message"), [
    ('do = "impair"\nloss = 1.5', "timeline[0]: loss: a probability is between 0 and 1"),
    ('do = "impair"\nloss = "lots"', "loss: expected a probability 0…1 or a percentage"),
    ('do = "impair"\ndelay = "100us"\njitter = "200us"', "jitter: at most the delay"),
    ('do = "impair"\ndelay = 300', "expected a duration with a unit"),
    ('do = "impair"\nloss = 0.1\nburst = 0.5', "burst: the mean length of a loss burst"),
    ('do = "impair"\nburst = 3', "burst: needs loss"),
    ('do = "impair"\nloss = 0.1\ndirection = "forward"',
     "direction: expected 'to-station', 'to-master' or 'both', got 'forward'"),
    ('do = "impair"', "nothing to do"),
    ('do = "impair"\nloss = 0.1\nfor = "0s"', "for: expected a duration above 0"),
    ('do = "run"\nhz = 5\ndirection = "to-master"', "direction: expected 'forward' or 'reverse', got 'to-master'"),
    ('do = "stop"\nloss = 0.1', "loss: 'do = \"stop\"' does not take it (it takes no field but station)"),
    ('do = "heal"\nfor = "1s"', "for: 'do = \"heal\"' does not take it (it takes name)"),
    ('do = "impair"\nlos = 0.1', "unknown field"),
])
def test_bad_values_name_the_step_and_the_field(step: str, message: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_config(BASE + f'[[timeline]]\nat = "1s"\n{step}\n')
    assert message in str(err.value)
