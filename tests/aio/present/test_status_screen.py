"""The live status as a terminal shows it (rendered by pyte): column headings, a legend, the manuals' ``21H``, and
at 60 columns every figure (the step, the longest host stall, each RTT) still on the screen; the final summary
wrapped to the terminal's width."""

from __future__ import annotations

import io
from types import SimpleNamespace

import pyte
import pytest

from mlink_sim.aio.present.status import COLUMNS, LiveStatus, StatusInfo, SummaryWriter, render_lines
from mlink_sim.config import parse_config
from mlink_sim.master import StationState
from mlink_sim.metrics import NetworkMetrics
from mlink_sim.wire import M2Status

CONFIG = parse_config("""
[network]
name = "screen"
transmission_cycle = "2ms"
[[station]]
address = 0x21
card = "si-t3"
[[station]]
address = 0x22
card = "si-t-v7"
[[station]]
address = 0x04
card = "si-et3"
[[timeline]]
at = "1s"
expect = "running"
""")

RTT = {0x21: 212_000, 0x22: 1_337_000, 0x04: 98_000}


class _Terminal(io.StringIO):
    """What rich writes, fed to a pyte screen of *columns* x *rows*."""

    def __init__(self, columns: int, rows: int) -> None:
        super().__init__()
        self.screen = pyte.Screen(columns, rows)
        self.stream = pyte.Stream(self.screen)

    def isatty(self) -> bool:
        return True

    def write(self, text: str) -> int:
        self.stream.feed(text.replace("\n", "\r\n"))
        return len(text)

    def shown(self) -> str:
        return "\n".join(line.rstrip() for line in self.screen.display)


def _view(address: int) -> SimpleNamespace:
    return SimpleNamespace(status=int(M2Status.RUNX) if address == 0x21 else 0, fault=False, alarm=0, comm_alm=0,
                           cmd_alm=0, warning=False, alarm_name=None, rtt_ns=RTT[address], phase=3,
                           state=StationState.PHASE3, output_freq=address)


def _info() -> StatusInfo:
    metrics = NetworkMetrics(2_000_000)
    metrics.missed = 4
    metrics.record_stall("master", 5, 23_900_000, 11, True)
    scales = {a: SimpleNamespace(to_hz=lambda raw: 30.0 if raw == 0x21 else 0.0) for a in RTT}
    return StatusInfo(config=CONFIG, net=SimpleNamespace(view=_view), metrics=metrics, scales=scales,
                      elapsed_s=3.5, total_s=12.0, step="10s station 21H: run forward at 30 Hz", p99_ns=1_500_000)


@pytest.mark.parametrize("columns", [60, 120])
def test_the_screen_names_its_columns_and_keeps_every_figure(columns: int) -> None:
    term = _Terminal(columns, 24)
    status = LiveStatus(term, size=(columns, 24))
    status.start()
    status.stop(render_lines(_info(), status.width))
    shown = term.shown()
    assert all(heading in shown for heading in COLUMNS)
    assert "P3: phase" in shown and "ok: no alarm" in shown and "missed:" in shown and "stalls:" in shown
    for figure in ("3.5/12.0 s", "p99 1.5ms", "missed 4", "max 23.9ms", "step 10s station 21H", "30.00 Hz",
                   "0.21 ms", "1.34 ms", "0.10 ms"):
        assert figure in shown, (figure, shown)
    assert "0x" not in shown and "21H" in shown and "22H" in shown and "04H" in shown
    assert "…" not in shown  # nothing cut


def test_the_narrow_layout_drops_padding_first() -> None:
    wide = render_lines(_info(), 120)
    narrow = render_lines(_info(), 60)
    rows = [line for line in narrow if line.lstrip().startswith(("21H", "22H", "04H"))]
    assert len(rows) == 3 and all(len(line) <= 60 for line in rows)
    assert max(map(len, rows)) < max(len(line) for line in wide if line.lstrip().startswith("21H"))
    assert len(narrow[0]) <= 60 and any("step 10s" in line for line in narrow[:3])


def test_the_summary_is_wrapped_to_the_terminal() -> None:
    out = io.StringIO()
    writer = SummaryWriter(out, 40)
    print("  FAIL 2s station 21H: expect output-hz 40±0.5 Hz: output 10.79 Hz after a 10 s ramp", file=writer)
    print("short", file=writer, flush=True)
    lines = out.getvalue().splitlines()
    assert all(len(line) <= 40 for line in lines) and len(lines) >= 4
    assert lines[0].startswith("  FAIL") and lines[1].startswith("      ") and lines[-1] == "short"
    assert " ".join(" ".join(lines).split()) == (
        "FAIL 2s station 21H: expect output-hz 40±0.5 Hz: output 10.79 Hz after a 10 s ramp short")
    unwrapped = io.StringIO()
    print("x" * 200, file=SummaryWriter(unwrapped, None))
    assert unwrapped.getvalue() == "x" * 200 + "\n"
