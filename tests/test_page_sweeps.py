"""docs/sweeps.md's example and messages are the code's: the full example is the shipped file with
its point count, and every error line the page shows is the one the command prints for the input
the test builds here (the memory a machine has available, and the cause a network gives for an
unreachable scheduler, are the two things not compared)."""
from __future__ import annotations

import copy
import json
import re
import tomllib

import pytest

from frogsim.cli import main
from page_numbers import NUM, ROOT, check, page, section

DOC = page("sweeps.md")
EXAMPLE = ROOT / "examples" / "sweep-source-saturation.toml"
RAW = tomllib.loads(EXAMPLE.read_text())


def test_the_full_example_is_the_shipped_file_and_its_point_count():
    block = re.search(r"A full example \(`examples/sweep-source-saturation.toml`.*?```toml\n(.*?)```", DOC, re.S).group(1)
    body = "\n".join(line for line in EXAMPLE.read_text().splitlines() if not line.startswith("#")).strip()
    assert block.strip() == body
    from frogsim.sweep import load_spec
    spec = load_spec(str(EXAMPLE))
    m = re.search(r"every combination: (\d+) x (\d+) x (\d+) = (\d+) points", block)
    assert tuple(int(x) for x in m.groups()[:3]) == spec.shape and int(m.group(4)) == spec.n_points


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return "{ " + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + " }"


def _dumps(d: dict, prefix: str = "") -> str:
    """TOML of a spec dict: its values inline, its sub-tables as [tables] (keys quoted)."""
    tables = {k: v for k, v in d.items() if isinstance(v, dict)}
    lines = [f"{json.dumps(k)} = {_value(v)}" for k, v in d.items() if k not in tables]
    out = ("\n".join(lines) + "\n") if lines else ""
    for k, v in tables.items():
        name = f"{prefix}.{json.dumps(k)}" if prefix else json.dumps(k)
        out += f"\n[{name}]\n" + _dumps(v, name)
    return out


def _message(raw, capsys, tmp_path, *extra) -> str:
    path = tmp_path / "spec.toml"
    (tmp_path / "one-hip.toml").write_text((ROOT / "examples" / "one-hip.toml").read_text())
    text = _dumps(raw)
    assert tomllib.loads(text) == raw
    path.write_text(text)
    out = tmp_path / "out.nc"
    assert main(["sweep", str(path), "--out", str(out), "--quiet", *extra]) == 2
    assert not out.exists()
    err = capsys.readouterr().err.strip()
    assert "\n" not in err, err
    return err


def _with(**changes):
    raw = copy.deepcopy(RAW)
    for path, value in changes.items():
        where = raw
        keys = path.split("/")
        for k in keys[:-1]:
            where = where[k]
        where[keys[-1]] = value
    return raw


def _page_lines(after: str) -> list[str]:
    block = re.search(re.escape(after) + r".*?```text\n(.*?)```", DOC, re.S).group(1)
    return block.splitlines()


AVAILABLE = re.compile(r"\([\d.]+ [kMGT]?B available")


def test_the_refusals_the_page_shows(capsys, tmp_path):
    lines = _page_lines("Any problem is one line naming the field")
    params = RAW["sweep"]["parameters"]
    cases = [
        _with(**{"sweep/parameters": {**params, "source.volum": {"start": "1 L", "stop": "2 L", "num": 2}}}),
        _with(**{"sweep/parameters": {**params, "source.volume": {"start": "2 L", "stop": "2 L", "num": 2}}}),
        _with(**{"sweep/parameters": {**params, "source.initial_pressure_gauge": {"values": ["3 bar", "lots"]}}}),
        _with(**{"record/metrics": ["speed"]}),
        _with(**{"base/overrides": {**RAW["base"]["overrides"], "pump.enabled": True},
                 "sweep/parameters": {"pump.on_below_gauge": {"values": ["6.2 bar"]}}}),
    ]
    got = [_message(raw, capsys, tmp_path) for raw in cases]
    # the scheduler: the page's address, unreachable here; the cause in brackets is the network's
    sched = re.search(r"--scheduler = '(tcp://[\d.:]+)'", lines[-1]).group(1)
    msg = _message(RAW, capsys, tmp_path, "--scheduler", "tcp://127.0.0.1:9")
    got.append(msg.replace("tcp://127.0.0.1:9", sched))
    assert len(lines) == len(got)
    for want, have in zip(lines[:-1], got[:-1]):
        assert want == have
    cut = lambda s: s.split(" (", 1)[0]      # noqa: E731
    assert cut(lines[-1]) == cut(got[-1]), (lines[-1], got[-1])
    assert "within 5 s" in got[-1]


def test_the_size_refusal_the_page_shows(capsys, tmp_path):
    want = " ".join(_page_lines("e.g. for `num = 1000000000`"))
    raw = _with(**{"sweep/parameters": {"source.initial_pressure_gauge": {"start": "3 bar", "stop": "6 bar",
                                                                          "num": 1000000000}}})
    got = _message(raw, capsys, tmp_path)
    assert AVAILABLE.sub("(N available", want) == AVAILABLE.sub("(N available", got)


def test_the_label_example_is_the_example_sweeps_third_branch_limit():
    """The page's label example: the third value of examples/sweep-source-saturation.toml's
    log-spaced branch limits (15 to 180 L/min in 8 steps: 15 x 12^(2/7) = 30.50906 L/min, 6
    significant digits in the unit written), as the sweep labels it."""
    import re
    from pathlib import Path

    from frogsim.sweep.runner import _written_text
    from frogsim.sweep.spec import load_spec
    root = Path(__file__).resolve().parents[1]
    text = " ".join((root / "docs" / "sweeps.md").read_text().split())
    label = re.search(r'`"(\d+\.\d+ L/min)"`, the third of `examples/sweep-source-saturation.toml`', text).group(1)
    spec = load_spec(root / "examples" / "sweep-source-saturation.toml")
    limit = next(p for p in spec.parameters if p.path == "supply.branch_limit")
    assert _written_text(limit.written[2]) == label == f"{15 * 12 ** (2 / 7):.6g} L/min"


def test_the_units_example_and_the_time_series_size():
    """"Units: one convention": a branch limit written "45 L/min" is stored as the page says, with
    the attributes it names, and a final_pressure in Pa with its display factor (one point of the
    example spec, run in memory); "Limits": the example's time series has 201 samples of float64 a
    point, so 10,000 points hold the megabytes the page gives per state."""
    from frogsim.sweep import load_spec, run_sweep
    raw = _with(**{"sweep/parameters": {"source.initial_pressure_gauge": ["6 bar"], "supply.branch_limit": ["45 L/min"],
                                        "muscles.hip.motion.fraction": [1.0]}})
    ds = run_sweep(load_spec(raw, base_dir=ROOT / "examples"), workers=1, progress=False)
    text = " ".join(DOC.split())
    m = re.search(r'a branch limit written `"45 L/min"` is stored as `([\d.e+-]+)` with `units = "([^"]+)"`, '
                  r'`display_units = "([^"]+)"`, `display_factor = ([\d.e+-]+)`', text)
    assert m, text[:200]
    limit = ds["supply.branch_limit"]
    assert float(m.group(1)) == pytest.approx(float(limit.values[0]), rel=1e-12)
    assert (m.group(2), m.group(3)) == (limit.attrs["units"], limit.attrs["display_units"])
    assert m.group(4) == f"{limit.attrs['display_factor']:.5g}"
    m = re.search(r'a `final_pressure` of ([\d.]+) bar gauge is stored as `([\d.]+)` with `units = "([^"]+)"`, '
                  r'`display_units = "([^"]+)"`, `display_factor = ([\d.e+-]+)`', text)
    p = ds["final_pressure"]
    assert (m.group(3), m.group(4)) == (p.attrs["units"], p.attrs["display_units"])
    assert float(m.group(5)) == p.attrs["display_factor"]
    assert m.group(2) == repr(float(m.group(1)) * p.attrs["display_factor"])
    series = ds["muscle_pressure"]
    limits = " ".join(section(DOC, "## Limits").split())
    m = re.search(r"10,000 points x (\d+) samples is (\d+) MB per state", limits)
    assert int(m.group(1)) == series.sizes["time"] and series.dtype.itemsize == 8
    check(limits, [(r"samples is " + NUM + " MB per state", 10_000 * series.sizes["time"] * 8 / 1e6)])
