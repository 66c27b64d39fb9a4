"""Parameters by name for the master's requests (mlink_sim.master.named), the decoded fields of a StationView and
requests whose body cannot be encoded, refused when they are made (sans-I/O)."""

from __future__ import annotations

import pickle

import pytest

from mlink_sim.master import (
    MasterCore,
    NetworkPlan,
    ParamRequestError,
    ParamValue,
    StationPlan,
    StationState,
    StationView,
    status_bits,
)
from mlink_sim.master import named
from mlink_sim.params import ParamError
from mlink_sim.wire import InvCmdStat, Link, M2Status, ml2, ml3

T3 = StationPlan(0x21, Link.ML2, card="si-t3")
V7 = StationPlan(0x22, Link.ML2, card="si-t-v7")
ET3 = StationPlan(0x04, Link.ML3, card="si-et3")


def test_si_t3_table_8_c1_01_by_name_is_register_0200h():
    assert named.read_target(T3, "C1-01") == (0x0200, named.table_for(T3).by_name("C1-01"))
    assert named.read_target(T3, "c1-01")[0] == 0x0200  # case-insensitive, as the keypad's names


def test_a_register_number_keeps_the_raw_api():
    assert named.read_target(T3, 0x0200) == (0x0200, None)
    assert named.write_target(T3, 0x0200, 50) == (0x0200, b"\x32\x00", None)
    assert named.write_target(T3, 0x0200, -1) == (0x0200, b"\xff\xff", None)  # two's complement


def test_the_card_picks_the_table_v7_n_numbers_for_si_t_v7():
    assert named.read_target(V7, "n019")[0] == 0x0113  # VS-606V7 MEMOBUS register 0100H + n
    with pytest.raises(ParamRequestError, match=r"station 22H \(SI-T/V7\): unknown parameter 'C1-01'"):
        named.read_target(V7, "C1-01")
    assert named.read_target(ET3, "C1-01")[0] == 0x0200  # SI-ET3 §9 PRM_RD example
    # an ML-III station without a card name is an SI-ET3 (the only ML-III card)
    assert named.table_for(StationPlan(0x04, Link.ML3)) is named.table_for(ET3)


def test_prm_wr_by_name_converts_by_the_tables_scale():
    register, data, param = named.write_target(T3, "C1-01", 5.0)
    assert (register, data, param.name) == (0x0200, b"\x32\x00", "C1-01")  # 50 counts of 0.1 s
    assert named.write_target(T3, "C1-01", "5 s")[1] == b"\x32\x00"  # keypad text too
    assert named.write_target(V7, "n020", 1.0)[:2] == (0x0114, b"\x0a\x00")
    assert named.write_target(T3, "C1-01", 5.0, size=4)[1] == b"\x32\x00\x00\x00"


@pytest.mark.parametrize(("plan", "target", "value", "match"), [
    (T3, "C1-01", 7000.0, r"station 21H \(SI-T3\): C1-01: 7000.0 s is out of range 0.0 … 6000.0 s"),
    (T3, "C1-01", 5.05, r"finer than the setting resolution of 0.1 s \(allowed: 0.0 … 6000.0 s\)"),
    (T3, "C1-01", "fast", r"'fast' is not a number"),
    (T3, "C1-01", None, r"None is not a number"),
    (T3, "U1-02", 1.0, r"U1-02 \(Output Frequency\) is read-only"),
    (T3, "C9-99", 1.0, r"unknown parameter 'C9-99'.*did you mean"),
    (T3, 0x0200, 1.5, r"register 0200H takes a raw int"),
    (T3, 0x10000, 1, r"neither a parameter name .* nor a register number"),
    (T3, "C1-01", 1.0, None),
])
def test_a_bad_name_type_or_value_raises_one_value_error(plan, target, value, match):
    if match is None:
        named.write_target(plan, target, value)
        return
    with pytest.raises(ParamRequestError, match=match) as err:
        named.write_target(plan, target, value)
    assert isinstance(err.value, ValueError) and isinstance(err.value, ParamError)
    assert err.value.station == plan.address and err.value.allowed and err.value.name


def test_range_error_carries_station_name_and_allowed_range():
    with pytest.raises(ParamRequestError) as err:
        named.write_target(T3, "C1-01", -1.0)
    assert (err.value.station, err.value.name, err.value.allowed) == (0x21, "C1-01", "0.0 … 6000.0 s")


def test_a_bad_size_is_refused():
    with pytest.raises(ParamRequestError, match="SIZE 3 is not 2, 4, 6 or 8"):
        named.read_target(T3, "C1-01", 3)


def test_a_station_without_a_known_card_takes_registers_only():
    with pytest.raises(ParamRequestError, match="its card is not known"):
        named.read_target(StationPlan(0x21, Link.ML2), "C1-01")


def test_param_value_reads_and_compares_as_a_float():
    param = named.table_for(T3).by_name("C1-01")
    v = named.value_of(param, b"\x64\x00")
    assert v == 10.0 and v > 9.5 and v + 1 == 11.0 and isinstance(v, float)
    assert (v.name, v.unit, v.raw, v.register, v.value) == ("C1-01", "s", 100, 0x0200, 10.0)
    assert str(v) == "10.0 s" and f"{v}" == "10.0 s" and f"{v:.2f}" == "10.00"
    assert "ParamValue('C1-01', 10.0, 's', raw=100, register=0x0200)" == repr(v)
    assert pickle.loads(pickle.dumps(v)).unit == "s"


def test_param_value_of_a_signed_row_is_sign_extended():
    table = named.table_for(T3)
    signed = next(p for p in table if p.signed)  # a signed monitor
    v = named.value_of(signed, (-1 & 0xFFFF).to_bytes(2, "little"))
    assert v.raw == -1 and v == pytest.approx(-signed.scale)


def test_a_hex_row_reads_as_the_keypad_shows():
    table = named.table_for(T3)
    h1 = next(p for p in table if p.radix == 16 and not p.read_only)
    assert str(named.value_of(h1, h1.default.to_bytes(2, "little"))).endswith("H")
    assert isinstance(ParamValue("X", 1.0, "", 1, 0), float)


# --- the StationView's decoded fields -------------------------------------------------------------------------------


def _view(link: str, status: int, card: str = "", output_freq: int = 0, hz_per_count: float = 0.0,
          **fields) -> StationView:
    base = dict(address=0x21, name="", state=StationState.PHASE3, phase=3, at_target=True, alarm=0, alarm_name=None,
                comm_alm=0, cmd_alm=0, fault=False, warning=False, status=status, output_freq=output_freq,
                output_current=0, mon1=0, mon2=0, rtt_ns=None, last_response_ns=None, wdt=0, rwdt=0, sent=0,
                responses=0, missing=0, late=0, recoveries=0, last_error=None, link=link, card=card,
                hz_per_count=hz_per_count)
    base.update(fields)
    return StationView(**base)


def test_output_hz_at_the_drives_resolution():
    assert _view("ML2", 0, output_freq=627, hz_per_count=0.01).output_hz == 6.27  # not 6.2700000000000005
    assert _view("ML2", 0, output_freq=3000, hz_per_count=0.1).output_hz == 300.0
    assert _view("ML2", 0, output_freq=627).output_hz is None  # units not known
    assert _view("ML2", 0, output_freq=627, hz_per_count=0.01).output_freq == 627  # raw kept


def test_si_t3_status_field_bits_by_name():
    status = M2Status.CMDRDY | M2Status.RUNX | M2Status.AGREE | M2Status.ZERO_SERVO
    view = _view("ML2", int(status), "si-t3")
    assert view.status_bits == ("CMDRDY", "RUNX", "AGREE", "ZERO_SERVO")
    assert view.bit("runx") and view.bit("AGREE") and not view.bit("REV")
    with pytest.raises(ValueError, match="no status bit 'SPEED'"):
        view.bit("SPEED")


def test_si_t_v7_status_field_has_no_bits_e_and_f():
    status = int(M2Status.RUNX | M2Status.SEL_M | M2Status.ZERO_SERVO)  # V7 §7.3: E and F not used
    assert status_bits(Link.ML2, status, "si-t-v7") == ("RUNX",)
    assert status_bits(Link.ML2, status, "si-t3") == ("RUNX", "SEL_M", "ZERO_SERVO")


def test_si_et3_invcmd_stat_bits_by_name():
    status = int(InvCmdStat.FORWARD | InvCmdStat.AGREE | InvCmdStat.SEL_MON1)
    assert _view("ML3", status, "si-et3").status_bits == ("FORWARD", "AGREE", "SEL_MON1")


def test_alarm_text_names_the_code():
    assert _view("ML2", 0, alarm=0xE6, alarm_name="COMM_ERROR").alarm_text == "E6H COMM_ERROR"
    assert _view("ML2", 0).alarm_text is None
    assert _view("ML3", 0, comm_alm=8, cmd_alm=0).alarm_text.startswith("COMM_ALM 8H ")


def test_the_core_view_carries_link_card_and_units():
    plan = NetworkPlan(Link.ML2, 2_000_000, (StationPlan(0x21, Link.ML2, card="si-t3", hz_per_count=0.01),))
    view = MasterCore(plan).view(0x21)
    assert (view.link, view.card, view.hz_per_count) == ("ML2", "si-t3", 0.01)


# --- a body that cannot be encoded is refused when the request is made -------------------------------------------


@pytest.mark.parametrize(("link", "mod"), [(Link.ML2, ml2), (Link.ML3, ml3)])
def test_a_request_whose_body_does_not_fit_is_refused_before_it_is_queued(link, mod):
    core = MasterCore(NetworkPlan(link, 2_000_000, (StationPlan(0x21, link),)))
    with pytest.raises(ValueError, match="station 21H: PrmRd cannot be sent"):
        core.request(0x21, mod.PrmRd("C1-01", 2))
    with pytest.raises(ValueError, match="cannot be sent"):
        core.request(0x21, mod.PrmRd(0x10000, 2))
    assert all(not core.on_cycle(k, k * 2_000_000) or True for k in range(3))  # the cycle still encodes
