"""Resuming: a sweep killed (SIGKILL) part-way and run again loses no finished point, runs no point
twice, leaves a readable results file at every moment, and ends equal to an uninterrupted run."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from sweep_helpers import GRID, interrupted, write_case

from frogsim.errors import ScenarioError
from frogsim.sweep import load_spec, read_results, run_sweep
from frogsim.sweep import runner

# the grid of sweep_helpers with a small solver step, so each point takes about 0.1 s and the
# process can be killed while it works; chunks of 2 points
SLOW = GRID.replace('scenario = "one-hip.toml"',
                    'scenario = "one-hip.toml"\n[base.overrides]\n"solver.max_step" = "0.005 ms"'
                    ).replace("chunk_size = 5", "chunk_size = 2")


def _vars(ds):
    return [v for v in ds.data_vars]


def assert_same_results(a, b):
    assert _vars(a) == _vars(b)
    for name in _vars(a):
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


def _chunk_files(parts):
    try:
        return sorted(f.name for f in parts.iterdir() if f.name.startswith("chunk-"))
    except FileNotFoundError:
        return []


def test_sigkill_part_way_then_rerun_completes(tmp_path):
    spec_path = write_case(tmp_path, SLOW)
    out = tmp_path / "results.nc"
    parts = tmp_path / "results.nc.parts"
    cmd = [sys.executable, "-m", "frogsim", "sweep", str(spec_path), "--out", str(out), "--workers", "1"]
    seen = []
    for kill_after in (2, 5):             # kill twice, each time once that many chunks are on disk
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 60
        while len(_chunk_files(parts)) < kill_after and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert proc.poll() is None, "the sweep ended before it could be interrupted: " + proc.stderr.read()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stderr.close()
        seen = _chunk_files(parts)
        assert len(seen) >= kill_after
        # whatever the moment, the results file is a complete, readable NetCDF file
        partial = read_results(out)
        assert int(partial["completed"].sum()) <= 24
        assert not any(f.name.startswith(".") for f in tmp_path.iterdir())   # no stray temp files
    done_before = 2 * len(seen)
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    # the rerun took every chunk finished before the kill, and ran only the rest
    line = next(ln for ln in p.stderr.splitlines() if ln.startswith("resuming"))
    assert int(line.split(":")[1].split()[0]) >= done_before, line
    final = read_results(out)
    assert not parts.exists()
    assert final.attrs["complete"] == 1 and final.attrs["n_completed"] == 24
    assert bool(final["completed"].all()) and not bool(final["failed"].any())
    reference = run_sweep(spec_path, workers=2, progress=False)      # uninterrupted, in memory
    assert_same_results(final, reference)


def test_interrupted_in_process_resumes_and_refuses_another_spec(tmp_path, monkeypatch):
    spec_path = write_case(tmp_path)           # 24 points, chunks of 5
    out = tmp_path / "r.nc"
    interrupted(monkeypatch, spec_path, out, after=2)
    assert len(_chunk_files(tmp_path / "r.nc.parts")) == 2
    assert int(read_results(out)["completed"].sum()) == 10     # brought up to date on Ctrl-C
    # a different spec must not mix into this run
    other = tmp_path / "other.toml"
    other.write_text(spec_path.read_text().replace("num = 4", "num = 3"))
    with pytest.raises(ScenarioError, match="r.nc.*(another spec|interrupted sweep of another spec)"):
        run_sweep(other, out=out, progress=False)
    assert len(_chunk_files(tmp_path / "r.nc.parts")) == 2
    # the same spec resumes: only the missing chunks run
    real, calls = runner.run_built, []
    monkeypatch.setattr(runner, "run_built", lambda *a, **k: (calls.append(2), real(*a, **k))[1])
    ds = run_sweep(spec_path, out=out, workers=1, progress=False)
    assert calls.count(2) == len(load_spec(spec_path).chunks()) - 2
    assert ds.attrs["n_points_read"] == 10 and "n_points_read" not in read_results(out).attrs
    assert_same_results(read_results(out), ds)
    assert_same_results(ds, run_sweep(spec_path, progress=False))


def test_the_command_says_how_many_points_it_ran_and_how_many_it_read(tmp_path, monkeypatch, capsys):
    from frogsim.cli import main
    spec_path = write_case(tmp_path)           # 24 points, chunks of 5
    out = tmp_path / "r.nc"
    interrupted(monkeypatch, spec_path, out, after=2)
    monkeypatch.undo()
    capsys.readouterr()
    assert main(["sweep", str(spec_path), "--out", str(out)]) == 0
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("14 points run in ") and ", 10 read from the earlier run -> " in last, last
