"""The sweep journal and the sweep's identity: a damaged chunk file is detected at resume and run
again (the results equal an uninterrupted run); a changed input file of the base scenario (here a
joint-angle CSV) makes the resume refuse, naming the file; --overwrite starts afresh. And the
results file's units: every variable and coordinate has one, in SI."""
import json
import zipfile

import numpy as np
import pytest
from sweep_helpers import GRID, ONE_HIP, interrupted, write_case

from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.sweep import load_spec, read_results, run_sweep
from frogsim.sweep import runner


def same(a, b):
    assert list(a.data_vars) == list(b.data_vars)
    for name in a.data_vars:
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


def counting(monkeypatch) -> list:
    real = runner.run_built
    calls = []
    monkeypatch.setattr(runner, "run_built", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    return calls


@pytest.mark.parametrize("damage", ["truncated", "bit flipped", "arrays altered, old checksum", "no checksum"])
def test_damaged_chunk_is_detected_and_run_again(tmp_path, monkeypatch, capsys, damage):
    spec_path = write_case(tmp_path)                   # 24 points, chunks of 5
    out = tmp_path / "r.nc"
    chunks = interrupted(monkeypatch, spec_path, out, after=3)
    assert len(chunks) == 3
    out.unlink()                # as if killed before the results file caught up: only the journal has them
    victim = chunks[1]
    data = victim.read_bytes()
    if damage == "truncated":
        victim.write_bytes(data[: len(data) // 2])
    elif damage == "bit flipped":
        with zipfile.ZipFile(victim) as z:                 # flip a bit inside a metric's stored bytes
            info = z.getinfo("m_rise_time.npy")
        at = info.header_offset + 30 + len(info.filename) + len(info.extra) + info.file_size - 3
        flipped = bytearray(data)
        flipped[at] ^= 0x10
        victim.write_bytes(bytes(flipped))
    else:
        with np.load(victim) as z:
            arrays = {k: z[k] for k in z.files}
        if damage == "no checksum":
            del arrays["sha256"]
        else:
            arrays["m_rise_time"] = arrays["m_rise_time"] * 1.001      # plausible, wrong numbers
        with open(victim, "wb") as fh:
            np.savez(fh, **arrays)
    calls = counting(monkeypatch)
    capsys.readouterr()
    ds = run_sweep(spec_path, out=out, workers=1, progress=True)
    n_chunks = len(load_spec(spec_path).chunks())
    assert len(calls) == n_chunks - 2                  # the damaged chunk ran again with the missing ones
    assert "damaged chunk" in capsys.readouterr().err
    same(ds, run_sweep(spec_path, progress=False))     # equal to an uninterrupted run
    same(read_results(out), ds)


def test_a_sound_journal_is_used_as_is(tmp_path, monkeypatch):
    spec_path = write_case(tmp_path)
    out = tmp_path / "r.nc"
    interrupted(monkeypatch, spec_path, out, after=3)
    out.unlink()
    calls = counting(monkeypatch)
    run_sweep(spec_path, out=out, workers=1, progress=False)
    assert len(calls) == len(load_spec(spec_path).chunks()) - 3


ANGLES = "time_s,hip_deg\n0,0\n0.1,0\n0.3,5\n0.5,5\n"
JOINT_BASE = ONE_HIP.replace('name = "one-hip"', 'name = "one-hip-angles"').replace(
    'motion = { kind = "volume_constant", fraction = 0.5 }',
    'motion = { kind = "joint_angles", file = "angles.csv", column = "hip_deg" }')
JOINT_GRID = GRID.replace('"muscles.hip.motion.fraction" = [0.0, 1.0]\n', "")


def test_changed_input_csv_refuses_to_resume(tmp_path, monkeypatch, capsys):
    (tmp_path / "angles.csv").write_text(ANGLES)
    spec_path = write_case(tmp_path, JOINT_GRID, JOINT_BASE)         # 12 points, chunks of 5
    spec = load_spec(spec_path)
    assert "muscles.hip.motion.file" in {f["role"] for f in spec.inputs}
    out = tmp_path / "r.nc"
    interrupted(monkeypatch, spec_path, out, after=1)
    (tmp_path / "angles.csv").write_text(ANGLES.replace(",5\n", ",6\n"))    # the table changed
    assert load_spec(spec_path).hash != spec.hash
    before = out.read_bytes()
    with pytest.raises(ScenarioError, match=r"angles\.csv.*changed.*--overwrite"):
        run_sweep(spec_path, out=out, workers=1, progress=False)
    assert out.read_bytes() == before                                   # nothing touched
    capsys.readouterr()
    assert main(["sweep", str(spec_path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "angles.csv" in err
    # without the results file, the journal's manifest names the file too
    out.unlink()
    with pytest.raises(ScenarioError, match=r"angles\.csv.*changed"):
        run_sweep(spec_path, out=out, workers=1, progress=False)
    # --overwrite starts afresh with the new table
    calls = counting(monkeypatch)
    ds = run_sweep(spec_path, out=out, workers=1, progress=False, overwrite=True)
    assert len(calls) == len(spec.chunks())
    same(ds, run_sweep(spec_path, progress=False))


def test_changed_parameter_set_file_is_named(tmp_path, monkeypatch):
    from frogsim.scenario.load import PARAMS_DIR
    params = tmp_path / "myset.toml"
    params.write_text((PARAMS_DIR / "fan2017.toml").read_text())
    base = JOINT_BASE.replace('motion = { kind = "joint_angles", file = "angles.csv", column = "hip_deg" }',
                              'motion = { kind = "volume_constant", fraction = 0.5 }')
    spec_path = write_case(tmp_path, JOINT_GRID, 'parameters = "myset.toml"\n' + base)
    out = tmp_path / "r.nc"
    interrupted(monkeypatch, spec_path, out, after=1)
    params.write_text(params.read_text() + "\n# edited\n")               # content, not values, changed
    with pytest.raises(ScenarioError, match=r"parameters file .*myset\.toml changed"):
        run_sweep(spec_path, out=out, workers=1, progress=False)


def test_every_variable_and_coordinate_has_si_units(tmp_path):
    path = write_case(tmp_path, GRID.replace("num = 4", "num = 2"))
    run_sweep(path, out=tmp_path / "r.nc", workers=2, progress=False)
    import xarray as xr
    with xr.open_dataset(tmp_path / "r.nc") as f:          # as written, not through read_results
        for name in f.variables:
            assert isinstance(f[name].attrs.get("units"), str) and f[name].attrs["units"], name
            assert f[name].attrs.get("long_name"), name
        assert f["final_pressure"].attrs["units"] == "Pa" and "gauge" in f["final_pressure"].attrs["long_name"]
        assert f["source_drop"].attrs["units"] == "Pa"
        assert f["aeration_volume"].attrs["units"] == "m3"
        assert f["valves.charge.sonic_conductance"].attrs["units"] if "valves.charge.sonic_conductance" in f \
            else True
        assert f["supply.branch_limit"].attrs["units"] == "m3 s-1"
        assert f["source.initial_pressure_gauge"].attrs["units"] == "Pa"
        # display units for plots: bar and L/min
        assert (f["final_pressure"].attrs["display_units"], f["final_pressure"].attrs["display_factor"]) == ("bar", 1e5)
        assert f["supply.branch_limit"].attrs["display_units"] == "L/min"
        # a gauge pressure of a few bar, in Pa
        fp = f["final_pressure"].values
        assert np.nanmin(fp) > 1e5 and np.nanmax(fp) < 7e5
        assert json.loads(f.attrs["input_files"])[0]["role"] == "scenario"


def test_format_1_file_is_read_in_si(tmp_path):
    path = write_case(tmp_path, GRID.replace("num = 4", "num = 2"))
    ds = run_sweep(path, progress=False)
    old = ds.copy(deep=True)                 # the same results as the previous layout wrote them
    old.attrs["frogsim_sweep_format"] = 1
    old["final_pressure"] = old["final_pressure"] / 1e5
    old["final_pressure"].attrs = {"units": "bar (gauge)"}
    old["aeration_volume"] = old["aeration_volume"] / 1e-3
    old["aeration_volume"].attrs = {"units": "L (standard)"}
    old["supply.branch_limit"].attrs["units"] = "m^3/s"
    runner.write_dataset(old, tmp_path / "old.nc")
    f = read_results(tmp_path / "old.nc")
    assert f["final_pressure"].attrs["units"] == "Pa" and f["aeration_volume"].attrs["units"] == "m3"
    assert np.allclose(f["final_pressure"].values, ds["final_pressure"].values, rtol=1e-14)
    assert np.allclose(f["aeration_volume"].values, ds["aeration_volume"].values, rtol=1e-14)
    assert f["supply.branch_limit"].attrs["units"] == "m3 s-1"


def test_a_journal_path_taken_by_a_file_is_refused_on_every_retry(tmp_path, capsys):
    """results.nc.parts replaced by a regular file: one line naming the path and what to do, exit 2,
    every time; the file is left as it was and no results file is made."""
    spec_path = write_case(tmp_path)
    out = tmp_path / "r.nc"
    parts = tmp_path / "r.nc.parts"
    parts.write_text("not a folder")
    for _ in range(2):
        assert main(["sweep", str(spec_path), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert str(parts) in err and "is a file" in err and ("delete" in err or "another --out" in err)
    assert parts.read_text() == "not a folder" and not out.exists()
