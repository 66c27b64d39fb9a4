"""The shipped Lua dissector under the real tshark: every packet of the golden capture (every command and response
of the three manuals, bad FCS, alarms) and of a real quickstart run decodes as ``mlink-sim decode`` says."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from mlink_sim.capture import read_capture
from mlink_sim.wire import DropReason, WireError, decode, describe

from .conftest import ROOT, run_tshark, tshark_packets

GOLDEN = Path(__file__).with_name("golden.pcapng")




def _int(text: str) -> int:
    return int(text, 0)


def check_envelope(layer: dict[str, Any] | None, data: bytes) -> dict[str, Any] | None:
    """Station, command names, data size and FCS verdict of the dissector equal ``decode``'s; returns describe()
    of the frame (None for a datagram decode rejects)."""
    assert layer is not None, "the dissector did not take the packet"
    assert _int(layer["mlink.station"]) == data[3]
    assert int(layer["mlink.data_size"]) == len(data) - 14
    try:
        d = describe(decode(data))
    except WireError as exc:
        assert exc.reason is DropReason.BAD_FCS, exc
        assert layer["mlink.fcs.status"] == "0"
        assert "mlink.fcs.bad" in layer["mlink.fcs_tree"]["_ws.expert"]
        return None
    assert layer["mlink.fcs.status"] == "1"
    assert layer["mlink.cmd.name"] == d["main"]["command"]
    if "sub" in d:
        assert layer["mlink.subcmd.name"] == d["sub"]["command"]
    else:
        assert "mlink.subcmd.name" not in layer
    return d


#: what the dissector adds to a body beside its fields: the parameter by name, INV_CTL's speed in Hz
_ADDED = ("mlink.param", "mlink.param.value", "mlink.speed_ref.hz", "mlink.output_freq.hz")


def _body_values(tree: Any) -> dict[str, str]:
    """The body fields of a ``mlink.main``/``mlink.sub`` subtree (an empty body is shown as "")."""
    if not isinstance(tree, dict):
        return {}
    return {k.removeprefix("mlink."): v for k, v in tree.items()
            if k.startswith("mlink.") and not k.endswith("_tree") and k not in _ADDED}


def check_fields(layer: dict[str, Any], d: dict[str, Any]) -> None:
    """Every field of the frame: body fields, WDT/RWDT, ALARM and its name, STATUS, CMD_STAT, SUB_STAT."""
    for region in ("main", "sub"):
        if region not in d:
            continue
        body = d[region]
        shown = _body_values(layer.get(f"mlink.{region}"))
        if body.get("unknown"):
            assert shown == {"raw": ":".join(body["raw"][i:i + 2] for i in range(0, len(body["raw"]), 2))}
            continue
        expected = {k: v for k, v in body.items() if k not in ("command", "code")}
        assert set(shown) == set(expected), (region, shown, expected)
        for k, v in expected.items():
            got = shown[k].replace(":", "") if isinstance(v, str) else _int(shown[k])
            assert got == v, (region, k, got, v)
        if body["command"] == "INV_CTL":  # in Hz by the default units (no note names them): 0.01 Hz per count
            tree = layer[f"mlink.{region}"]
            for k in ("speed_ref", "output_freq"):
                if k in body:
                    assert float(tree[f"mlink.{k}.hz"]) == pytest.approx(body[k] * 0.01), k
    for key in ("wdt", "rwdt", "alarm", "status", "substatus"):
        if key in d:
            assert _int(layer[f"mlink.{key}"]) == d[key], key
    if d.get("alarm"):
        assert layer["mlink.alarm.name"] == d["alarm_name"]
    if "cmd_stat" in d:
        tree = layer["mlink.cmd_stat_tree"]
        for key in ("cmd_alm", "comm_alm", "rcmd_id"):
            assert _int(tree[f"mlink.cmd_stat.{key}"]) == d["cmd_stat"][key], key
        for key in ("d_alm", "d_war", "cmdrdy", "alm_clr_cmp"):
            assert tree[f"mlink.cmd_stat.{key}"] == str(int(d["cmd_stat"][key])), key
    if "cmd_ctrl" in d:
        tree = layer["mlink.cmd_ctrl_tree"]
        assert tree["mlink.cmd_ctrl.alm_clr"] == str(int(d["cmd_ctrl"]["alm_clr"]))
        assert _int(tree["mlink.cmd_ctrl.cmd_id"]) == d["cmd_ctrl"]["cmd_id"]
    if "sub_stat" in d:
        tree = layer["mlink.sub_stat_tree"]
        assert _int(tree["mlink.sub_stat.subcmd_alm"]) == d["sub_stat"]["subcmd_alm"]


def test_golden_capture_covers_every_command_of_the_manuals() -> None:
    from mlink_sim.wire import ml2, ml3

    seen: dict[str, set[tuple[str, int]]] = {}
    for dg in read_capture(GOLDEN).datagrams:
        try:
            d = describe(decode(dg.data))
        except WireError:
            continue
        gen = "ml3" if d["link"] == "ML3" else "ml2"
        kind = "cmd" if d["kind"] == "command" else "rsp"
        seen.setdefault(f"{gen}.{kind}.main", set()).add(d["main"]["code"])
        if "sub" in d:
            seen.setdefault(f"{gen}.{kind}.sub", set()).add(d["sub"]["code"])
    for name, slot in (("ml2.cmd.main", ml2.COMMAND_MAIN), ("ml2.rsp.main", ml2.RESPONSE_MAIN),
                       ("ml2.cmd.sub", ml2.COMMAND_SUB), ("ml2.rsp.sub", ml2.RESPONSE_SUB),
                       ("ml3.cmd.main", ml3.COMMAND_MAIN), ("ml3.rsp.main", ml3.RESPONSE_MAIN),
                       ("ml3.cmd.sub", ml3.COMMAND_SUB), ("ml3.rsp.sub", ml3.RESPONSE_SUB)):
        assert set(slot.by_code) <= seen[name], name


def test_golden_capture_through_tshark_equals_decode(tshark: str) -> None:
    datagrams = read_capture(GOLDEN).datagrams
    layers = tshark_packets(tshark, GOLDEN)
    assert len(layers) == len(datagrams) == 126
    bad = 0
    for layer, dg in zip(layers, datagrams):
        d = check_envelope(layer, dg.data)
        if d is None:
            bad += 1
            continue
        check_fields(layer, d)
    assert bad == 3  # one bad FCS per link


def test_golden_capture_display_filters(tshark: str) -> None:
    def count(expr: str) -> int:
        return len(run_tshark(tshark, GOLDEN, "-Y", expr).splitlines())

    assert count("mlink.fcs.status == 0") == 3
    assert count("mlink.fcs.bad") == 3
    assert count('mlink.alarm.name == "COMM_ERROR"') == 1
    assert count("mlink.cmd_stat.comm_alm == 0xc") == 1  # WDT_ERROR (SI-ET3 "COMM_ALM")
    assert count("mlink.station == 0x31 && mlink.cmd == 0x50") == 2  # INV_CTL command + response
    assert count("mlink.unknown") == 2
    assert count("mlink.status.alm == 1 && mlink.alarm == 0x08") == 1  # drive alarm ov, SI-T3 Table 26


@pytest.mark.e2e
def test_quickstart_capture_through_tshark_equals_decode(tshark: str, tmp_path: Path) -> None:
    capture = tmp_path / "quickstart.pcapng"
    proc = subprocess.run([sys.executable, "-m", "mlink_sim", "up", str(ROOT / "configs" / "quickstart.toml"),
                           "--duration", "1s", "--no-status", "--capture", str(capture)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode in (0, 1), proc.stderr  # 1: a timeline check failed on a loaded machine, still a capture
    assert f"capture {capture}:" in proc.stderr
    datagrams = read_capture(capture).datagrams
    layers = tshark_packets(tshark, capture)
    assert len(layers) == len(datagrams) > 500
    for layer, dg in zip(layers, datagrams):
        check_envelope(layer, dg.data)
    assert {dg.data[3] for dg in datagrams} == {0x21, 0x22, 0x23}
    assert {dg.data[2] for dg in datagrams} == {1, 2}
    comments = [c for dg in datagrams for c in dg.comments]
    for station in ("21H", "22H", "23H"):  # the master's events: bring-up as packet comments
        assert f"StateChanged station {station}: old=syncing new=phase3" in comments


@pytest.fixture(scope="module")
def virtual_quickstart(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quickstart on the virtual clock, recorded: its master's card notes and the timeline's set-param steps
    (n020 on the SI-T/V7 22H, C1-02 on the SI-ET3 23H)."""
    capture = tmp_path_factory.mktemp("virtual") / "quickstart.pcapng"
    proc = subprocess.run([sys.executable, "-m", "mlink_sim", "up", "quickstart", "--clock", "virtual", "--no-status",
                           "--duration", "3.4s", "--capture", str(capture)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return capture


def _decode_params(capture: Path) -> list[tuple[int, str, str]]:
    """``(frame number, parameter name, value text)`` of every PRM_RD/PRM_WR body ``mlink-sim decode`` names."""
    from mlink_sim.cli.frame_names import FrameNames

    names = FrameNames()
    out = []
    for number, dg in enumerate(read_capture(capture).datagrams, 1):
        for comment in dg.comments:
            names.learn(comment)
        d = names.describe(decode(dg.data))
        for region in ("main", "sub"):
            param = d.get(region, {}).get("param")
            if param is not None:
                out.append((number, param["name"], param["text"].split(" = ", 1)[1] if "value" in param else ""))
    return out


def _tshark_params(tshark: str, capture: Path, *options: str) -> list[tuple[int, str, str]]:
    out = run_tshark(tshark, capture, *options, "-Y", "mlink.param", "-T", "fields", "-e", "frame.number",
                     "-e", "mlink.param", "-e", "mlink.param.value")
    rows = []
    for line in out.splitlines():
        number, name, value = (line.split("\t") + ["", ""])[:3]
        rows.append((int(number), name, value))
    return rows


def test_parameters_by_name_as_decode_names_them(tshark: str, virtual_quickstart: Path) -> None:
    expected = _decode_params(virtual_quickstart)
    assert {(name, value) for _, name, value in expected} >= {("n020", "1.0 s"), ("C1-02", "1.0 s")}
    assert _tshark_params(tshark, virtual_quickstart) == expected


def test_the_cards_preference_picks_the_table(tshark: str, virtual_quickstart: Path) -> None:
    rows = _tshark_params(tshark, virtual_quickstart, "-o", "mlink.cards:22H=si-t3")
    assert rows and all(name != "n020" for _, name, _ in rows)  # 0114H is no A1000 parameter
    info = run_tshark(tshark, virtual_quickstart, "-Y", "mlink.param")
    assert "22H cmd INV_CTL / PRM_WR n020 (0114H) = 1.0 s cycle" in info
