"""mlink_sim.metrics.assertions: the --assert expression language (docs/report.md)."""

from __future__ import annotations

import pytest

from mlink_sim.metrics import (
    AssertionSyntaxError,
    NetworkMetrics,
    assertable_fields,
    check_all,
    parse_assertion,
    parse_assertions,
)

US = 1_000
MS = 1_000_000


def hist(p99: int = 0, count: int = 100) -> dict:
    return {"count": count, "min": 1, "p50": 2, "p90": 3, "p99": p99, "p99_9": p99, "max": p99, "mean": 2}


def station(p99: int, late: int = 0, count: int = 100) -> dict:
    return {"rtt": hist(p99, count), "sent": 100, "answered": count, "late": late, "missing": 0,
            "reception_failures": 0, "wdt_errors": 0, "dropped": 0}


REPORT = {
    "cycles": 30000, "missed": 3, "missed_rate": 0.0001,
    "rtt": hist(731_200), "lateness": hist(0, count=0),
    "sent": 300, "answered": 300, "late": 1, "missing": 0, "reception_failures": 0, "wdt_errors": 0,
    "dropped": 0,
    "cpu": {"master": 12.5, "slaves": 30.1, "by_process": {}},
    "station": {"0x21": station(400 * US), "0x22": station(1_200 * US, late=1), "0x23": station(700 * US)},
}


# ------------------------------------------------------------------------------------------ parsing
@pytest.mark.parametrize(
    "text, path, op, bound, kind",
    [
        ("rtt.p99 < 500us", ("rtt", "p99"), "<", 500_000, "time"),
        ("missed == 0", ("missed",), "==", 0, "count"),
        ("station[0x21].rtt.p99 < 1ms", ("station", "0x21", "rtt", "p99"), "<", 1_000_000, "time"),
        ("station[33].rtt.p99 < 1ms", ("station", "0x21", "rtt", "p99"), "<", 1_000_000, "time"),
        ("station[0X2A].late <= 2", ("station", "0x2a", "late"), "<=", 2, "count"),
        ("station[ 5 ].sent >= 1", ("station", "0x05", "sent"), ">=", 1, "count"),
        ("station[*].missing == 0", ("station", "*", "missing"), "==", 0, "count"),
        ("rtt.p99.9 <= 2 ms", ("rtt", "p99_9"), "<=", 2_000_000, "time"),
        ("rtt.p99_9 != 0", ("rtt", "p99_9"), "!=", 0, "time"),
        ("  lateness.max>250us  ", ("lateness", "max"), ">", 250_000, "time"),
        ("rtt.count >= 29000", ("rtt", "count"), ">=", 29000, "count"),
        ("cpu.master < 50%", ("cpu", "master"), "<", 50, "percent"),
        ("cpu.slaves < 75.5", ("cpu", "slaves"), "<", 75.5, "percent"),
        ("missed_rate < 1%", ("missed_rate",), "<", 0.01, "ratio"),
        ("missed_rate <= 0.001", ("missed_rate",), "<=", 0.001, "ratio"),
        ("rtt.max ≤ 1s", ("rtt", "max"), "<=", 10**9, "time"),
        ("wdt_errors ≠ 1", ("wdt_errors",), "!=", 1, "count"),
    ],
)
def test_good_expressions(text, path, op, bound, kind):
    a = parse_assertion(text)
    assert (a.path, a.op, a.bound, a.kind) == (path, op, bound, kind)
    assert a.text == text.strip()
    assert parse_assertion(str(a)) == parse_assertion(str(a))          # normalised text parses again
    assert parse_assertion(str(a)).bound == bound


@pytest.mark.parametrize(
    "value, ns",
    [("1ns", 1), ("500us", 500_000), ("500µs", 500_000), ("500μs", 500_000), ("0.5ms", 500_000),
     ("0.1ms", 100_000), ("1.5ns", 1.5), ("2s", 2_000_000_000), ("1e3ns", 1000), (".25ms", 250_000),
     ("250 us", 250_000), ("0", 0), ("0ms", 0), ("3.", None)],
)
def test_time_units(value, ns):
    if ns is None:
        with pytest.raises(AssertionSyntaxError, match="time unit"):
            parse_assertion(f"rtt.p50 < {value}")
        return
    a = parse_assertion(f"rtt.p50 < {value}")
    assert a.bound == ns and type(a.bound) is type(ns)


def test_normalised_text():
    assert str(parse_assertion("station[33].rtt.p99.9<500µs")) == "station[0x21].rtt.p99_9 < 500us"
    assert str(parse_assertion("station[*].late==0")) == "station[*].late == 0"
    assert str(parse_assertion("missed_rate < 1%")) == "missed_rate < 1%"


def test_a_station_as_the_manuals_write_it():
    assert str(parse_assertion("station[21H].late == 0")) == "station[0x21].late == 0"
    assert str(parse_assertion("station[3eh].late == 0")) == "station[0x3e].late == 0"


def test_stations_known_before_the_run():
    assert parse_assertion("station[0x21].late == 0", stations={0x21, 0x22}).path[1] == "0x21"
    assert parse_assertion("station[*].late == 0", stations={0x21}).path[1] == "*"
    with pytest.raises(AssertionSyntaxError) as e:
        parse_assertion("station[0x24].late == 0", stations={0x21, 0x22, 0x23})
    assert str(e.value) == ("expected a station of the configuration (0x21, 0x22, 0x23) at column 9, "
                            "got '0x24'")


@pytest.mark.parametrize(
    "text, message",
    [
        ("rtt.p99 500us",
         "expected a comparison operator (<, <=, ==, !=, >=, >) after 'rtt.p99' at column 9, got '500us'"),
        ("rtt.p99",
         "expected a comparison operator (<, <=, ==, !=, >=, >) after 'rtt.p99' at column 8, "
         "got the end of the expression"),
        ("rtt.p99 = 5ms",
         "expected a comparison operator (<, <=, ==, !=, >=, >) after 'rtt.p99' at column 9, got '=' "
         "(use '==' to test equality)"),
        ("rtt.p99 => 5ms",
         "expected a comparison operator (<, <=, ==, !=, >=, >) after 'rtt.p99' at column 9, got '=>' "
         "(did you mean '>='?)"),
        ("", "expected a report field (e.g. rtt.p99, missed, station[0x21].late) at column 1, "
             "got the end of the expression"),
        ("< 5ms", "expected a report field (e.g. rtt.p99, missed, station[0x21].late) at column 1, got '<'"),
        ("rtt.p98 < 1ms",
         "expected a field of 'rtt' (count, min, p50, p90, p99, p99_9, max, mean) at column 5, got 'p98' "
         "(did you mean 'p99'?)"),
        ("latency.p99 < 1ms",
         "expected a field of the report (cycles, missed, missed_rate, rtt, lateness, sent, answered, late, "
         "missing, reception_failures, wdt_errors, dropped, foreign_source, cpu, station, host) at column 1, got 'latency' "
         "(did you mean 'lateness'?)"),
        ("rtt < 5ms",
         "expected '.' and a field of 'rtt' (count, min, p50, p90, p99, p99_9, max, mean) at column 4, got '<' "
         "('rtt' is a group of fields, not a value)"),
        ("rtt. < 5ms", "expected a field name after 'rtt.' at column 5, got '<'"),
        ("rtt[1].p99 < 1ms",
         "expected '.' or a comparison operator after 'rtt' at column 4, got '[' "
         "(only station[...] takes an address)"),
        ("station.late == 0",
         "expected '[' and a station address after 'station' (e.g. station[0x21]) at column 8, got '.'"),
        ("station[].late == 0",
         "expected a station address after 'station[' (21H or 0x21, decimal 33, or * for every station) "
         "at column 9, got ']'"),
        ("station[0x21 .late == 0", "expected ']' after the station address '0x21' at column 14, got '.'"),
        ("station[0x100].late == 0", "expected a station address from 0x00 to 0xff at column 9, got '0x100'"),
        ("station[0x21] < 1", "expected '.' and a field of 'station[0x21]' (rtt, sent, answered, late, missing, "
                              "alarms, reception_failures, wdt_errors, dropped, foreign_source, recovery, injected, unrecovered) at column 14, got '<' "
                              "('station[0x21]' is a group of fields, not a value)"),
        ("meta.duration_s > 1", "expected a field of the report (cycles, missed, missed_rate, rtt, lateness, sent, "
                                "answered, late, missing, reception_failures, wdt_errors, dropped, foreign_source, cpu, station, host) "
                                "at column 1, got 'meta'"),
        ("cpu.by_process < 5", "expected a field of 'cpu' (master, slaves) at column 5, got 'by_process'"),
        ("rtt.p99 <", "expected a number after '<' at column 10, got the end of the expression"),
        ("rtt.p99 < fast", "expected a number after '<' at column 11, got 'fast'"),
        ("rtt.p99 < -5us", "expected a number after '<' at column 11, got '-'"),
        ("rtt.p99 < 500",
         "expected a time unit (ns, us, µs, ms, s) after '500' at column 14, got the end of the expression "
         "('rtt.p99' is a time; only 0 may go without a unit)"),
        ("rtt.p99 < 5 sec",
         "expected a time unit (ns, us, µs, ms, s) after '5' at column 13, got 'sec' ('rtt.p99' is a time)"),
        ("rtt.p99 < 5%",
         "expected a time unit (ns, us, µs, ms, s) after '5' at column 12, got '%' ('rtt.p99' is a time)"),
        ("missed < 5ms",
         "expected a plain number for 'missed' at column 11, got 'ms' ('missed' is a count; it takes no unit)"),
        ("station[0x21].late < 1 %",
         "expected a plain number for 'station[0x21].late' at column 24, got '%' "
         "('station[0x21].late' is a count; it takes no unit)"),
        ("cpu.master < 5ms",
         "expected '%' or no unit after '5' at column 15, got 'ms' ('cpu.master' is a percentage)"),
        ("missed_rate < 1ms",
         "expected '%' or no unit after '1' at column 16, got 'ms' "
         "('missed_rate' is a ratio from 0 to 1; write 1% or 0.01)"),
        ("rtt.p99 < 1ms && missed == 0",
         "expected the end of the expression at column 15, got '&&' (give each condition its own --assert)"),
        ("rtt.p99 < 1ms and missed == 0",
         "expected the end of the expression at column 15, got 'and' (give each condition its own --assert)"),
        ("rtt.p99 < 1ms)", "expected the end of the expression at column 14, got ')'"),
    ],
)
def test_syntax_errors(text, message):
    with pytest.raises(AssertionSyntaxError) as e:
        parse_assertion(text)
    assert str(e.value) == message
    assert isinstance(e.value, ValueError) and e.value.text == text


def test_syntax_error_caret_points_at_column():
    with pytest.raises(AssertionSyntaxError) as e:
        parse_assertion("rtt.p99 500us")
    line, caret = e.value.caret().splitlines()
    assert line[caret.index("^")] == "5" and e.value.column == 9


def test_parse_assertions_raises_first_error():
    assert len(parse_assertions(["missed == 0", "late == 0"])) == 2
    with pytest.raises(AssertionSyntaxError, match="after 'late'"):
        parse_assertions(["missed == 0", "late 0", "x"])


def test_every_schema_field_is_assertable():
    fields = assertable_fields()
    for path, kind in fields.items():
        text = path.replace("ADDR", "0x21")
        value = {"time": "1ms", "count": "1", "percent": "1%", "ratio": "0.5"}[kind]
        assert parse_assertion(f"{text} < {value}").kind == kind
    assert fields["rtt.p99"] == "time" and fields["station[ADDR].late"] == "count"


# ------------------------------------------------------------------------------------------ checking
@pytest.mark.parametrize(
    "text, ok, measured, message",
    [
        ("rtt.p99 < 500us", False, 731_200, "rtt.p99 < 500us failed: measured 731.2us"),
        ("rtt.p99 < 1ms", True, 731_200, "rtt.p99 < 1ms ok: measured 731.2us"),
        ("rtt.p99 <= 731.2us", True, 731_200, "rtt.p99 <= 731.2us ok: measured 731.2us"),
        ("rtt.p99 < 731.2us", False, 731_200, "rtt.p99 < 731.2us failed: measured 731.2us (731200ns)"),
        ("missed == 0", False, 3, "missed == 0 failed: measured 3"),
        ("missed <= 3", True, 3, "missed <= 3 ok: measured 3"),
        ("missed != 3", False, 3, "missed != 3 failed: measured 3"),
        ("missed >= 4", False, 3, "missed >= 4 failed: measured 3"),
        ("missed > 2", True, 3, "missed > 2 ok: measured 3"),
        ("station[0x21].rtt.p99 < 1ms", True, 400_000, "station[0x21].rtt.p99 < 1ms ok: measured 400us"),
        ("station[34].rtt.p99 < 1ms", False, 1_200_000, "station[0x22].rtt.p99 < 1ms failed: measured 1.2ms"),
        ("station[0x30].late == 0", False, None,
         "station[0x30].late == 0 failed: no field 'station[0x30]' in the report (stations: 0x21, 0x22, 0x23)"),
        ("lateness.p99 < 100us", False, None, "lateness.p99 < 100us failed: no samples ('lateness.count' is 0)"),
        ("lateness.count == 0", True, 0, "lateness.count == 0 ok: measured 0"),
        ("cpu.master < 50%", True, 12.5, "cpu.master < 50% ok: measured 12.5%"),
        ("cpu.slaves < 30", False, 30.1, "cpu.slaves < 30 failed: measured 30.1%"),
        ("missed_rate < 0.01%", False, 0.0001, "missed_rate < 0.01% failed: measured 0.0001 (0.01%)"),
        ("station[*].rtt.p99 < 2ms", True, 1_200_000,
         "station[*].rtt.p99 < 2ms ok at all 3 stations: worst station[0x22] 1.2ms"),
        ("station[*].rtt.p99 < 650us", False, 1_200_000,
         "station[*].rtt.p99 < 650us failed at 2 of 3 stations: station[0x22] measured 1.2ms, "
         "station[0x23] measured 700us"),
        ("station[*].rtt.p99 > 500us", False, 400_000,
         "station[*].rtt.p99 > 500us failed at 1 of 3 stations: station[0x21] measured 400us"),
        ("station[*].late == 0", False, 1, "station[*].late == 0 failed at 1 of 3 stations: station[0x22] measured 1"),
    ],
)
def test_check_messages(text, ok, measured, message):
    r = parse_assertion(text).check(REPORT)
    assert (r.ok, r.measured, r.message) == (ok, measured, message)


def test_wildcard_without_stations_fails():
    r = parse_assertion("station[*].late == 0").check({**REPORT, "station": {}})
    assert not r.ok and r.message == "station[*].late == 0 failed: no stations in the report"


def test_wildcard_reports_missing_samples():
    report = {**REPORT, "station": {"0x21": station(400 * US), "0x22": station(0, count=0)}}
    r = parse_assertion("station[*].rtt.p99 < 1ms").check(report)
    assert not r.ok and r.measured == 400 * US
    assert r.message == ("station[*].rtt.p99 < 1ms failed at 1 of 2 stations: "
                         "station[0x22] no samples ('station[0x22].rtt.count' is 0)")


def test_wildcard_lists_at_most_five():
    report = {**REPORT, "station": {f"0x{a:02x}": station(2 * MS + a) for a in range(0x21, 0x29)}}
    r = parse_assertion("station[*].rtt.p99 < 1ms").check(report)
    assert r.message.startswith("station[*].rtt.p99 < 1ms failed at 8 of 8 stations: station[0x28] measured")
    assert r.message.endswith(", ...") and r.message.count("measured") == 5


def test_odd_report_values_fail_without_raising():
    for bad in ({**REPORT, "missed": "3"}, {**REPORT, "missed": None}, {**REPORT, "missed": True}, {}):
        r = parse_assertion("missed == 0").check(bad)
        assert not r.ok and r.measured is None
    r = parse_assertion("rtt.p99 < 1ms").check({"rtt": 5})
    assert not r.ok and "no field 'rtt.p99'" in r.message


def test_check_all_against_a_real_report():
    m = NetworkMetrics(cycle_ns=MS)
    for k in range(1000):
        m.record_cycle_lateness(10 * US)
        m.record_sent(0x21)
        m.record_rtt(0x21, (k + 1) * US)
    report = m.report(meta={"config": "c", "started": "2024-01-01T00:00:00Z", "duration_s": 1.0})
    results = check_all(parse_assertions(["rtt.p99 < 500us", "missed == 0", "station[0x21].rtt.p99 < 1ms"]),
                        report)
    assert [r.ok for r in results] == [False, True, True]
    assert results[0].message == "rtt.p99 < 500us failed: measured 990.2us"
    d = results[0].as_dict()
    assert d == {"text": "rtt.p99 < 500us", "ok": False, "measured": report["rtt"]["p99"], "bound": 500_000,
                 "message": "rtt.p99 < 500us failed: measured 990.2us"}
