"""`frogsim log` as a checked reader of the firmware's serial log (format 2): the bytes come from a
fake pyserial port (serial.Serial replaced), firmware.json is written here, and every expected
value comes from the stream each test builds, not from the reader's output.

The stream: a header ``# frogsim NAME rate=R channels=SIG@A0 muscles=M log_every=L format=2
plan=HEX12``, then records ``k,counts,valvebits,faultbits,overruns,dropped``."""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from frogsim.cli import main
from frogsim.export.serial_log import parse_log

import serial  # noqa: E402  (pyserial: a dependency of frogsim, never skipped)

DIGEST = "0123456789abcdef" * 4
UPC = 1e6 / 819.2                   # [Pa/count] 0.5..4.5 V over 0..10 bar on a 10-bit ADC at 5 V
OFFSET = -102.4 * UPC + UPC / 2     # 0.5 V reads 0 bar; the middle of the count's step
REC = {
    "format": 2, "name": "stub", "rate_hz": 1000.0, "log_every": 10, "baud": 115200, "plan_sha256": DIGEST,
    "muscles": ["hip"], "adc": {"bits": 10, "prescaler": 128}, "f_cpu_hz": 16000000, "period_cycles": 16000,
    "valve_pins": [[22, 23]], "busy_pin": 13,
    "channels": [{"signal": "hip pressure", "quantity": "pressure", "name": "hold", "analog_input": 0,
                  "unit_per_count": UPC, "offset": OFFSET, "unit": "Pa gauge", "count_range": [0, 1023]}],
}
HEADER = b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip log_every=10 format=2 plan=0123456789ab\n"


def bar(count: int) -> float:
    return (count * UPC + OFFSET) / 1e5


def lines(*rows) -> bytes:
    return b"".join((",".join(str(x) for x in r) + "\n").encode() for r in rows)


class FakeSerial:
    """pyserial's Serial as `frogsim log` uses it: read(n) gives the next chunk, then b"" (a silent port)."""

    def __init__(self, data: bytes, chunk: int = 7):
        self.chunks = [data[i:i + chunk] for i in range(0, len(data), chunk)]
        self.closed = False

    def read(self, n):
        return self.chunks.pop(0) if self.chunks else b""

    def close(self):
        self.closed = True


@pytest.fixture
def fw(tmp_path) -> Path:
    folder = tmp_path / "fw"
    folder.mkdir()
    (folder / "firmware.json").write_text(json.dumps(REC))
    return folder


def run_log(monkeypatch, data: bytes, out: Path, *argv, idle: str = "0.3") -> int:
    ports = []

    def opener(port, baud, timeout):
        ports.append(FakeSerial(data))
        return ports[-1]
    monkeypatch.setattr(serial, "Serial", opener)
    code = main(["log", "--port", "fake0", *argv, "--idle-timeout", idle, "--out", str(out), "--quiet"])
    assert all(p.closed for p in ports)
    return code


def summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())["log"]


def csv(out: Path):
    import pandas as pd
    return pd.read_csv(out / "serial.csv")


def status(out: Path) -> str:
    return json.loads((out / "manifest.json").read_text())["status"]


# -- resynchronising on a line boundary -------------------------------------------------------------
def test_a_stream_starting_mid_line_drops_the_fragment(monkeypatch, fw, tmp_path, capsys):
    """The capture begins inside the record "1350,355,1,0,0,0": its tail "0,355,1,0,0,0" looks like a
    valid record at k = 0 but is a fragment; the first true record is k = 1360, count 102."""
    data = b"0,355,1,0,0,0\n" + lines((1360, 102, 1, 0, 0, 0), (1370, 110, 0, 0, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    df = csv(out)
    assert df["time [s]"].tolist() == pytest.approx([1.36, 1.37])
    assert df["hip pressure [bar gauge]"].tolist() == pytest.approx([bar(102), bar(110)])
    assert df["hip charge valve [1 = open]"].tolist() == [1, 0]
    s = summary(out)
    assert s["discarded"] == {"partial_first_line": 1}
    assert s["first"] == {"k": 1360, "time_s": 1.36} and s["last"] == {"k": 1370, "time_s": 1.37}
    err = capsys.readouterr().err
    assert "partial_first_line" in err and "no header line came" in err


def test_a_header_as_the_first_line_is_whole():
    """A capture from the board's start begins with its header ('#' begins no record's tail)."""
    log = parse_log(HEADER + lines((0, 102, 1, 0, 0, 0)), REC)
    assert log.header == HEADER.decode().strip() and log.records == [(0, 102, 1, 0, 0, 0)] and log.bad == 0


def test_the_first_record_keeps_its_value_after_a_fragment():
    log = parse_log(b"55,900,2,0,0,0\n" + HEADER + lines((0, 102, 1, 0, 0, 0), (10, 104, 1, 0, 0, 0)), REC)
    assert log.records == [(0, 102, 1, 0, 0, 0), (10, 104, 1, 0, 0, 0)]
    assert log.discarded == {"partial_first_line": 1}


# -- empty captures ---------------------------------------------------------------------------------
EMPTY = {
    "garbage": b"\x00\xffjunk\r\nmore junk, nothing here\n\xfe\xfe\n",
    "wrong column counts": HEADER + lines((0, 102), (10, 102, 1, 0), (20, 1, 2, 3, 4, 5, 6)),
    "nan": HEADER + b"nan,nan,nan,nan,nan,nan\n0,nan,1,0,0,0\n",
    "a header then silence": HEADER,
}


@pytest.mark.parametrize("case", list(EMPTY))
def test_an_empty_capture_fails_and_writes_no_csv(case, monkeypatch, fw, tmp_path, capsys):
    out = tmp_path / "log"
    assert run_log(monkeypatch, EMPTY[case], out, "--firmware", str(fw)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("frogsim: error: --port fake0: no valid record"), err
    assert f"{len(EMPTY[case])} bytes" in err[0]
    assert ("header 'frogsim stub" in err[0]) == (case != "garbage")
    assert status(out) == "failed"
    assert not (out / "serial.csv").exists() and not (out / "summary.json").exists()
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json"]


def test_an_empty_capture_names_the_discarded_reasons(monkeypatch, fw, tmp_path, capsys):
    out = tmp_path / "log"
    assert run_log(monkeypatch, EMPTY["wrong column counts"], out, "--firmware", str(fw)) == 1
    assert "field_count 3" in capsys.readouterr().err


def test_garbage_without_firmware_says_no_header(monkeypatch, tmp_path, capsys):
    out = tmp_path / "log"
    assert run_log(monkeypatch, b"x\n" + lines((0, 102, 1, 0, 0, 0)), out) == 1
    err = capsys.readouterr().err
    assert "no header line" in err and "before_header 1" in err and status(out) == "failed"
    assert not (out / "serial.csv").exists()


# -- records checked --------------------------------------------------------------------------------
def test_a_count_outside_its_range_is_refused(monkeypatch, fw, tmp_path, capsys):
    """99999 would read as about 1219 bar: refused, not written."""
    data = HEADER + lines((0, 102, 1, 0, 0, 0), (10, 99999, 1, 0, 0, 0), (20, 600, 0, 0, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    df = csv(out)
    assert df["hip pressure [bar gauge]"].tolist() == pytest.approx([bar(102), bar(600)])
    assert df["hip pressure [bar gauge]"].max() < 11
    assert summary(out)["discarded"] == {"count_out_of_range": 1}
    assert "count_out_of_range 1" in capsys.readouterr().err


def test_k_going_backwards_is_refused(monkeypatch, fw, tmp_path, capsys):
    data = HEADER + lines((0, 100, 0, 0, 0, 0), (10, 101, 0, 0, 0, 0), (0, 500, 0, 0, 0, 0),
                          (10, 501, 0, 0, 0, 0), (20, 102, 0, 0, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    df = csv(out)
    assert df["time [s]"].tolist() == pytest.approx([0.0, 0.01, 0.02])
    assert df["hip pressure [bar gauge]"].tolist() == pytest.approx([bar(100), bar(101), bar(102)])
    assert summary(out)["discarded"] == {"k_not_increasing": 2}
    assert "k_not_increasing 2" in capsys.readouterr().err


BAD_LINES = {
    "field_count": b"10,100,0,0,0\n",
    "not_a_number": b"10,1e2,0,0,0,0\n",
    "k_off_grid": b"15,100,0,0,0,0\n",
    "valvebits_out_of_range": b"10,100,4,0,0,0\n",
    "both_valves_open": b"10,100,3,0,0,0\n",
    "faultbits_out_of_range": b"10,100,0,2,0,0\n",
    "counter_out_of_range": b"10,100,0,0,65536,0\n",
    "counter_decreased": b"10,100,0,0,0,0\n",
    "comment_line": b"# dropped 3\n",
    "empty_line": b"\n",
}


@pytest.mark.parametrize("reason", list(BAD_LINES))
def test_each_bad_line_is_counted_by_its_reason(reason):
    first = (0, 101, 1, 0, 4, 1) if reason == "counter_decreased" else (0, 101, 1, 0, 0, 0)
    log = parse_log(HEADER + lines(first) + BAD_LINES[reason] + lines((20, 103, 2, 1, 4, 1)), REC)
    assert log.discarded == {reason: 1}
    assert [r[0] for r in log.records] == [0, 20]
    assert log.examples[0]["reason"] == reason


@pytest.mark.parametrize("text", [b"-10,100,0,0,0,0", b"10,+100,0,0,0,0", b"10,100.0,0,0,0,0",
                                  b"10,inf,0,0,0,0", b"10, 100,0,0,0,0", "10,\u00b2,0,0,0,0".encode()])
def test_only_unsigned_decimal_digits_are_numbers(text):
    log = parse_log(HEADER + text + b"\n", REC)
    assert log.records == [] and log.discarded == {"not_a_number": 1}


def test_a_run_on_line_is_dropped_without_holding_it():
    log = parse_log(HEADER + b"1" * 5000 + b"\n" + lines((0, 102, 1, 0, 0, 0)), REC)
    assert log.records == [(0, 102, 1, 0, 0, 0)] and log.discarded == {"line_too_long": 1}


# -- the header -------------------------------------------------------------------------------------
OTHER = {
    "name": (b"# frogsim other rate=1000 channels=hip pressure@A0 muscles=hip log_every=10 format=2 "
             b"plan=0123456789ab\n", "'stub'"),
    "rate": (b"# frogsim stub rate=500 channels=hip pressure@A0 muscles=hip log_every=10 format=2 "
             b"plan=0123456789ab\n", "'1000'"),
    "channels": (b"# frogsim stub rate=1000 channels=hip pressure@A1 muscles=hip log_every=10 format=2 "
                 b"plan=0123456789ab\n", "'hip pressure@A0'"),
    "muscles": (b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=knee log_every=10 format=2 "
                b"plan=0123456789ab\n", "'hip'"),
    "log_every": (b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip log_every=20 format=2 "
                  b"plan=0123456789ab\n", "10"),
    "plan": (b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip log_every=10 format=2 "
             b"plan=fedcba987654\n", "'0123456789ab'"),
    "format": (b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip\n", "2"),
}


@pytest.mark.parametrize("which", list(OTHER))
def test_a_header_of_another_firmware_is_refused(which, monkeypatch, fw, tmp_path, capsys):
    header, want = OTHER[which]
    out = tmp_path / "log"
    assert run_log(monkeypatch, header + lines((0, 102, 1, 0, 0, 0)), out, "--firmware", str(fw)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"frogsim: error: the serial log's header {which} = "), err
    assert f"firmware.json (--firmware) has {want}" in err[0]
    assert status(out) == "failed" and not (out / "serial.csv").exists()


def test_without_firmware_the_header_makes_the_plan(monkeypatch, tmp_path):
    header = b"# frogsim enc rate=500 channels=hip pressure@A0;knee angle@D2 muscles=hip;knee log_every=5 " \
             b"format=2 plan=0123456789ab\n"
    data = header + lines((0, 1023, 40000, 0b0001, 0, 0, 0), (5, 0, 3, 0b0110, 0b10, 0, 0),
                          (10, 7, 0, 0b1000, 0, 0, 0), (15, 1024, 0, 0, 0, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out) == 0
    df = csv(out)
    assert list(df.columns) == ["time [s]", "hip pressure [count]", "knee angle [count]",
                                "hip charge valve [1 = open]", "hip discharge valve [1 = open]",
                                "knee charge valve [1 = open]", "knee discharge valve [1 = open]"]
    assert df["time [s]"].tolist() == pytest.approx([0.0, 0.01, 0.02])
    assert df["hip pressure [count]"].tolist() == [1023, 0, 7]
    assert df["knee angle [count]"].tolist() == [40000, 3, 0]         # an encoder's count: no 10-bit bound
    assert df["hip discharge valve [1 = open]"].tolist() == [0, 1, 0]
    assert df["knee charge valve [1 = open]"].tolist() == [0, 1, 0]
    assert df["knee discharge valve [1 = open]"].tolist() == [0, 0, 1]
    s = summary(out)
    assert s["discarded"] == {"count_out_of_range": 1}          # 1024 is past a 10-bit analog count
    assert s["faults"] == {"samples": 1, "per_channel": {"hip pressure": 0, "knee angle": 1}}


def test_a_restart_keeps_the_last_run(monkeypatch, fw, tmp_path, capsys):
    data = lines((990, 300, 0, 0, 0, 0), (1000, 301, 0, 0, 0, 0), (1010, 302, 0, 0, 0, 0)) + HEADER + \
        lines((0, 102, 1, 0, 0, 0), (10, 103, 1, 0, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    assert csv(out)["time [s]"].tolist() == pytest.approx([0.0, 0.01])
    s = summary(out)
    assert s["discarded"] == {"partial_first_line": 1, "before_restart": 2} and s["restarts"] == 1
    assert "restarted" in capsys.readouterr().err


# -- counters, drops, faults ------------------------------------------------------------------------
def test_overruns_are_reported(monkeypatch, fw, tmp_path, capsys):
    data = HEADER + lines(*[(10 * i, 200, 0, 0, i + 1, 0) for i in range(103)])
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    s = summary(out)
    assert s["records"] == 103
    assert s["overruns"] == {"first": 1, "last": 103, "increase": 102, "saturated": False}
    err = capsys.readouterr().err
    assert "overran its period 102 times" in err and "1 -> 103" in err


def test_a_drop_is_reported_by_the_counter_and_the_k_gap(monkeypatch, fw, tmp_path, capsys):
    data = HEADER + lines((0, 200, 0, 0, 0, 0), (10, 201, 0, 0, 0, 0), (20, 202, 0, 0, 0, 0),
                          (50, 205, 0, 0, 0, 2), (60, 206, 0, 0, 0, 2))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    s = summary(out)
    assert s["dropped"] == {"first": 0, "last": 2, "increase": 2, "saturated": False, "missing_from_k_gaps": 2,
                            "agree": True}
    assert csv(out)["time [s]"].tolist() == pytest.approx([0.0, 0.01, 0.02, 0.05, 0.06])
    err = capsys.readouterr().err
    assert "dropped counter went 0 -> 2" in err and "miss 2 records" in err and "disagree" not in err


def test_a_gap_the_counter_does_not_explain_is_a_disagreement(monkeypatch, fw, tmp_path, capsys):
    data = HEADER + lines((0, 200, 0, 0, 0, 0), (40, 201, 0, 0, 0, 1))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    s = summary(out)["dropped"]
    assert (s["increase"], s["missing_from_k_gaps"], s["agree"]) == (1, 3, False)
    assert "disagree" in capsys.readouterr().err


def test_fault_bits_are_counted_per_channel(monkeypatch, fw, tmp_path, capsys):
    data = HEADER + lines((0, 200, 0, 1, 0, 0), (10, 201, 0, 0, 0, 0), (20, 202, 0, 1, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw)) == 0
    assert summary(out)["faults"] == {"samples": 2, "per_channel": {"hip pressure": 2}}
    assert "2 of 3 records have a channel read in fault (hip pressure 2)" in capsys.readouterr().err


def test_a_clean_capture_warns_only_that_the_idle_timeout_stopped_it(monkeypatch, fw, tmp_path, capsys):
    data = HEADER + lines((0, 200, 1, 0, 0, 0), (10, 201, 0, 0, 0, 0))
    out = tmp_path / "log"
    assert run_log(monkeypatch, data, out, "--firmware", str(fw), "--duration", "60", idle="0.3") == 0
    err = capsys.readouterr().err
    assert [ln for ln in err.splitlines() if ln.startswith("warning:")] == \
        ["warning: no byte came for 0.3 s (--idle-timeout): the capture stopped after "
         + f"{summary(out)['capture_s']:.1f} s"]
    s = summary(out)
    assert s["discarded"] == {} and s["records"] == 2 and s["bytes_read"] == len(data)
    assert s["idle_timeout"] == {"seconds": 0.3, "hit": True} and s["stopped_by"] == "idle timeout"
    assert status(out) == "complete"
    files = {f["name"] for f in json.loads((out / "manifest.json").read_text())["files"]}
    assert files == {"serial.csv", "summary.json"}


# -- stopping -----------------------------------------------------------------------------------------
def test_a_silent_port_stops_after_the_idle_timeout(monkeypatch, fw, tmp_path, capsys):
    out = tmp_path / "log"
    t0 = time.monotonic()
    assert run_log(monkeypatch, b"", out, "--firmware", str(fw), idle="0.5") == 1
    took = time.monotonic() - t0
    assert 0.4 < took < 10
    err = capsys.readouterr().err
    assert "0 bytes" in err and "stopped after 0.5 s without a byte" in err
    assert status(out) == "failed" and not (out / "serial.csv").exists()


def test_the_duration_stops_a_busy_port(monkeypatch, fw, tmp_path):
    class Endless:
        k = 0

        def read(self, n):
            time.sleep(0.01)
            self.k += 10
            return lines((self.k, 200, 0, 0, 0, 0))

        def close(self):
            pass
    monkeypatch.setattr(serial, "Serial", lambda port, baud, timeout: Endless())
    out = tmp_path / "log"
    t0 = time.monotonic()
    assert main(["log", "--port", "p", "--firmware", str(fw), "--duration", "0.5", "--out", str(out), "--quiet"]) == 0
    assert 0.4 < time.monotonic() - t0 < 10
    s = summary(out)
    assert s["stopped_by"] == "duration" and s["records"] > 5 and s["idle_timeout"]["hit"] is False


@pytest.mark.parametrize("flag", ["--duration", "--idle-timeout"])
@pytest.mark.parametrize("value", ["inf", "nan", "0", "-1"])
def test_a_time_that_is_not_finite_and_positive_is_refused(flag, value, fw, tmp_path, capsys):
    out = tmp_path / "log"
    code = main(["log", "--port", "fake0", "--firmware", str(fw), flag, value, "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"frogsim: error: {flag} = "), err
    assert "finite time in seconds > 0" in err[0] and "Traceback" not in "".join(err)
    assert not out.exists()


def test_a_firmware_json_of_an_unknown_format_is_refused(tmp_path, capsys):
    (tmp_path / "fw").mkdir()
    (tmp_path / "fw" / "firmware.json").write_text(json.dumps(REC | {"format": 5}))
    code = main(["log", "--port", "p", "--firmware", str(tmp_path / "fw"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "export it again" in err[0] and "format = 5" in err[0]
    assert not (tmp_path / "o").exists()


def test_a_firmware_json_with_a_bad_count_range_is_refused(tmp_path, capsys):
    rec = json.loads(json.dumps(REC))
    rec["channels"][0]["count_range"] = [10, 5]
    (tmp_path / "fw").mkdir()
    (tmp_path / "fw" / "firmware.json").write_text(json.dumps(rec))
    code = main(["log", "--port", "p", "--firmware", str(tmp_path / "fw"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "channels[0].count_range" in err[0]
    assert not (tmp_path / "o").exists()


def test_the_format_1_log_is_still_read():
    """The older firmware: k,counts,valvebits,overruns and '# dropped N' lines."""
    rec = REC | {"format": 1}
    log = parse_log(b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip\n"
                    + lines((0, 102, 1, 0), (10, 104, 1, 0), (40, 105, 2, 1)) + b"# dropped 2\n"
                    + lines((50, 106, 2, 1)), rec)
    assert log.records == [(0, 102, 1, 0), (10, 104, 1, 0), (40, 105, 2, 1), (50, 106, 2, 1)]
    assert log.bad == 0 and log.dropped == 2 and log.missing_from_k_gaps == 2


def test_a_long_field_is_garbage_not_a_huge_number():
    log = parse_log(HEADER + b"0," + b"9" * 1100 + b",0,0,0,0\n" + lines((10, 102, 1, 0, 0, 0)), REC)
    assert log.records == [(10, 102, 1, 0, 0, 0)] and log.discarded == {"line_too_long": 1}
