"""Small scenario and spec files shared by the sweep tests (short runs, tens of points)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from frogsim.sweep import run_sweep, runner

# one hip muscle held at a fixed volume, charged for 0.3 s then vented: 0.5 s per run
ONE_HIP = """
name = "one-hip"
duration = "0.5 s"
output_interval = "1 ms"
[controller]
rate = "1 kHz"
[programs.stroke]
pressurise = "0.3 s"
release = "0.2 s"
[muscles.hip]
type = "hip"
program = "stroke"
motion = { kind = "volume_constant", fraction = 0.5 }
"""

def source_pressure_sweep(points: int) -> str:
    """A sweep spec of ``points`` source pressures from 3 to 6 bar on one-hip.toml, recording the
    hip's rise time: the smallest sweep a command test needs."""
    return f"""
name = "small"
[base]
scenario = "one-hip.toml"
[sweep]
method = "grid"
[sweep.parameters]
"source.initial_pressure_gauge" = {{ start = "3 bar", stop = "6 bar", num = {int(points)} }}
[record]
metrics = ["rise_time"]
muscle = "hip"
"""


GRID = """
name = "grid-test"
[base]
scenario = "one-hip.toml"
[sweep]
method = "grid"
[sweep.parameters]
"source.initial_pressure_gauge" = { start = "3 bar", stop = "6 bar", num = 4 }
"supply.branch_limit" = { values = [15, 45, 180], unit = "L/min" }
"muscles.hip.motion.fraction" = [0.0, 1.0]
[record]
metrics = ["rise_time", "final_pressure", "aeration_volume", "source_drop"]
muscle = "hip"
timeseries = { states = ["muscle_pressure", "source_pressure"], interval = "10 ms" }
[run]
chunk_size = 5
"""


def write_case(folder: Path, spec: str = GRID, base: str = ONE_HIP, name: str = "spec.toml") -> Path:
    """Write the base scenario and a spec into folder; returns the spec path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "one-hip.toml").write_text(textwrap.dedent(base))
    path = folder / name
    path.write_text(textwrap.dedent(spec))
    return path


def interrupted(monkeypatch, spec_path, out, after: int) -> list:
    """Run the sweep until `after` chunks are done, then interrupt it (as Ctrl-C would)."""
    real = runner.run_built
    calls = []

    def failing(*args, **kw):
        if len(calls) == after:
            raise KeyboardInterrupt
        calls.append(1)
        return real(*args, **kw)
    monkeypatch.setattr(runner, "run_built", failing)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec_path, out=out, workers=1, progress=False)
    monkeypatch.setattr(runner, "run_built", real)
    return sorted((out.parent / f"{out.name}.parts").glob("chunk-*.npz"))
