"""One size check before any large job (frogsim._budget): a sweep or run asking for more points,
rows, memory or disk than allowed or available is refused up front, in seconds, with the figures;
nothing is made or written.

Lower bounds used as expected values come from the arrays alone: every point of a sweep holds at
least one 8-byte float per parameter and per metric, and a results file stores them."""
import time

import pytest
from sweep_helpers import write_case

import frogsim
from frogsim import _budget
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.sweep import load_spec, run_sweep

SPEC = """
name = "size"
[base]
scenario = "one-hip.toml"
[sweep]
method = "{method}"
{extra}
[sweep.parameters]
{params}
[record]
metrics = ["rise_time", "final_pressure"]
"""
P = '"source.initial_pressure_gauge"'
B = '"supply.branch_limit"'
V = '"valves.charge.dead_time"'
#: specs whose point count is past the 2,000,000-point limit; the count each asks for
HUGE = {
    "one range of 1e9": ("grid", "", f'{P} = {{ start = "3 bar", stop = "6 bar", num = 1000000000 }}', 10**9),
    "grid 2000 x 2000": ("grid", "", f'{P} = {{ start = "3 bar", stop = "6 bar", num = 2000 }}\n'
                                     f'{B} = {{ start = "10 L/min", stop = "90 L/min", num = 2000 }}', 4 * 10**6),
    "grid of three 300s": ("grid", "", f'{P} = {{ start = "3 bar", stop = "6 bar", num = 300 }}\n'
                                       f'{B} = {{ start = "10 L/min", stop = "90 L/min", num = 300 }}\n'
                                       f'{V} = {{ start = "1 ms", stop = "5 ms", num = 300 }}', 27 * 10**6),
    "1e9 random samples": ("random", "samples = 1000000000",
                           f'{P} = {{ min = "3 bar", max = "6 bar" }}', 10**9),
    "list of 1e9": ("list", "", f'{P} = {{ start = "3 bar", stop = "6 bar", num = 1000000000 }}\n'
                                f'{B} = {{ start = "10 L/min", stop = "90 L/min", num = 1000000000 }}', 10**9),
}


def _bytes(text: str) -> float:
    """"318 GB" -> 3.18e11."""
    num, unit = text.split()
    return float(num) * {"B": 1, "kB": 1e3, "MB": 1e6, "GB": 1e9, "TB": 1e12}[unit]


@pytest.mark.parametrize("case", sorted(HUGE))
def test_every_spec_past_the_point_limit_is_refused_in_seconds_with_the_memory_it_needs(tmp_path, case):
    method, extra, params, n = HUGE[case]
    path = write_case(tmp_path, SPEC.format(method=method, extra=extra, params=params))
    t0 = time.perf_counter()
    with pytest.raises(ScenarioError) as err:
        load_spec(path)
    assert time.perf_counter() - t0 < 5.0
    msg = str(err.value)
    assert f"a sweep of {n:,} points" in msg and "2,000,000 points allowed" in msg
    need = _bytes(msg.split("need about ")[1].split(" of memory")[0])
    n_params = params.count("\n") + 1
    assert need >= 8 * n * (n_params + 2)          # at least its SI values and two metrics


def test_the_cli_refuses_a_1e9_point_sweep_in_seconds(tmp_path, capsys):
    path = write_case(tmp_path, SPEC.format(method="grid", extra="", params=HUGE["one range of 1e9"][2]))
    t0 = time.perf_counter()
    assert main(["sweep", str(path), "--out", str(tmp_path / "r.nc"), "--quiet"]) == 2
    assert time.perf_counter() - t0 < 5.0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "num = 1000000000" in err and "of memory" in err
    assert not (tmp_path / "r.nc").exists() and not (tmp_path / "r.nc.parts").exists()


def test_a_sweep_within_the_count_but_past_the_memory_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(_budget, "available_memory", lambda: 100 * 10**6)     # 100 MB available
    params = f'{P} = {{ start = "3 bar", stop = "6 bar", num = 1000000 }}'
    path = write_case(tmp_path, SPEC.format(method="grid", extra="", params=params))
    with pytest.raises(ScenarioError, match=r"not enough memory.*|.*100 MB available.*") as err:
        load_spec(path)
    assert "points allowed" not in str(err.value)


def test_a_sweep_past_the_free_disk_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    params = f'{P} = {{ values = ["3 bar", "4 bar", "5 bar"] }}'
    path = write_case(tmp_path, SPEC.format(method="grid", extra="", params=params))
    spec = load_spec(path)
    assert spec.need(tmp_path / "r.nc").disk >= 3 * 8 * (1 + 2)     # its values and two metrics
    monkeypatch.setattr(_budget, "ASK_ABOVE", 0)
    monkeypatch.setattr(_budget, "free_disk", lambda p: 10)         # 10 bytes free
    with pytest.raises(ScenarioError, match=r"of disk \(10 B free\).*not enough disk"):
        run_sweep(path, out=tmp_path / "r.nc", progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one-hip.toml", "spec.toml"]


@pytest.mark.parametrize("duration,interval", [(3600.0, 1e-4), (1e6, 1e-3), (10.0, 1e-9)])
def test_every_run_past_the_output_row_limit_is_refused_with_its_rows(duration, interval):
    sc = frogsim.load_scenario("paper-cycle")
    rows = int(duration / interval) + 1
    with pytest.raises(ScenarioError) as err:
        sc.replace({"duration": duration, "output_interval": interval})
    msg = str(err.value)
    assert msg.startswith("output_interval") and f"{rows:,} output rows" in msg
    assert _bytes(msg.split("need about ")[1].split(" of memory")[0]) >= 8 * 2 * rows   # time + a pressure


def test_small_jobs_never_ask_the_system(monkeypatch):
    monkeypatch.setattr(_budget, "available_memory", lambda: pytest.fail("asked for a small job"))
    monkeypatch.setattr(_budget, "free_disk", lambda p: pytest.fail("asked for a small job"))
    _budget.check("x", 1, _budget.Need("a job", 10, "points", 100, memory=1e6, disk=1e6, disk_path="."))
