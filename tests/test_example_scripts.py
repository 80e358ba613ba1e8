"""The scripts of examples/ run as their docstrings say, and write exactly the files committed beside
them: the example data are what their scripts make (a change to the code or to a script that moves
a trace fails here; run the script and commit what it writes). The tank-heat script's printed start
of each recovery is the start the recovery fits use."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from page_numbers import same_as_written

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
# examples/rl trains a policy and writes a model, not data: tests/test_envs_v1.py runs it on a tiny budget
SCRIPTS = sorted(p for p in EXAMPLES.rglob("*.py") if "rl" not in p.relative_to(EXAMPLES).parts)


def run_from_copy(script: Path, tmp_path: Path) -> tuple[Path, str]:
    """Run the script as its docstring says, from the repository root, in a copy of examples/
    from which the CSV files of the script's folder were removed."""
    shutil.copytree(EXAMPLES, tmp_path / "examples")
    folder = tmp_path / script.parent.relative_to(ROOT)
    for f in folder.glob("*.csv"):
        f.unlink()
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join([str(ROOT / "src")] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    rel = script.relative_to(ROOT).as_posix()
    p = subprocess.run([sys.executable, rel], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    return folder, p.stdout


def test_every_script_says_how_to_run_it():
    for script in SCRIPTS:
        doc = script.read_text()
        rel = script.relative_to(ROOT).as_posix()
        assert f"python {rel}" in doc or script.name == "make_traces.py", rel


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.relative_to(EXAMPLES).as_posix())
def test_the_script_writes_the_committed_files(script, tmp_path):
    folder, _ = run_from_copy(script, tmp_path)
    committed = sorted(f.name for f in script.parent.glob("*.csv"))
    assert committed, script
    assert sorted(f.name for f in folder.glob("*.csv")) == committed, "the script writes other files"
    for name in committed:
        assert (folder / name).read_bytes() == (script.parent / name).read_bytes(), f"{name}: the script writes other data"


def test_the_tank_heat_recoveries_start_where_the_script_says(tmp_path):
    script = EXAMPLES / "fit" / "tank-heat" / "make_traces.py"
    _, out = run_from_copy(script, tmp_path)
    import frogsim
    atm = frogsim.load_scenario(str(script.parent / "vessel.toml")).air.atmospheric_pressure_abs
    found = re.findall(r"^(\w+) recovery from [\d.]+ s: ([\d.]+) K, pressure ([\d.]+) bar abs$", out, re.M)
    assert {name for name, *_ in found} == {"discharge", "filling"}, out
    for name, temperature, p_abs in found:
        raw = tomllib.loads((script.parent / f"FIT-{name}-recovery.toml").read_text())
        ov = raw["experiments"][0]["overrides"]
        assert ov["source.initial_temperature"] == f"{temperature} K"
        gauge = re.fullmatch(r"(-?[\d.]+) kPa", ov["source.initial_pressure_gauge"]).group(1)
        assert same_as_written(gauge, (float(p_abs) * 1e5 - atm) / 1e3), (name, gauge, p_abs, atm)
