"""The fit says what the data cannot fix, and its intervals stay honest: a parameter without effect
is "unidentifiable" (with the reason) and the others keep their intervals, the same as a fit
without it; an interval never leaves its parameter's bounds; correlated residuals widen the
intervals by their effective sample size; summary.json names its input files as the spec does.

Data: FESTO's DMSP-20 force-contraction table (examples/fit/force, from frogsim.components.dmsp20,
cited there) without its stretched rows (contraction < 0): the force law's two stretch constants act
only on stretched rows, so they have no effect on it (the law's definition, frogsim.physics.
muscle_force); a cheap model, so that these tests are fast."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from frogsim.cli import main
from frogsim.fit import fit

ROOT = Path(__file__).resolve().parents[1]
FESTO = ROOT / "examples" / "fit" / "force" / "dmsp20-festo.csv"
RIG = ROOT / "examples" / "fit" / "rig.toml"
THREE = {"muscle_force.force_scale": {"min": "0 N", "max": "1000 N", "start": "100 N"},
         "muscle_force.strain_scale": {"min": "0.2 %", "max": "20 %", "start": "3 %"},
         "muscle_force.stiffness": {"min": "0 N", "max": "5000 N", "start": "500 N"}}
STRETCH = {"muscle_force.stretch_stiffness": {"min": "0 N", "max": "50000 N", "start": "5000 N"},
           "muscle_force.stretch_quadratic": {"min": "0 N", "max": "1000000 N", "start": "200000 N"}}


def _table(tmp_path, keep) -> str:
    d = pd.read_csv(FESTO)
    d[keep(d)].to_csv(tmp_path / "t.csv", index=False)
    return "t.csv"


def _spec(tmp_path, table, params, **extra) -> dict:
    return {"base_dir": str(tmp_path), "scenario": str(RIG), "starts": 1,
            "force_tables": [{"table": table, "muscle": "hip", "noise": "50 N", "relative_noise": 0.1}],
            "parameters": params, **extra}


def test_constants_without_effect_are_unidentifiable_and_leave_the_others_alone(tmp_path):
    """The docs' force-table FIT.toml's five constants on a table without stretched rows: the two
    stretch constants "unidentifiable" (no effect), the other three with the intervals a fit of
    those three alone gives (before, every interval was NaN)."""
    table = _table(tmp_path, lambda d: d["contraction [%]"] >= 0)
    five = fit(_spec(tmp_path, table, {**THREE, **STRETCH}))
    three = fit(_spec(tmp_path, table, THREE))
    for p in STRETCH:
        assert "no effect" in five.unidentifiable[p]
    j = [five.paths.index(p) for p in THREE]
    assert np.all(np.isfinite(five.ci_low[j])) and np.all(np.isfinite(five.ci_high[j]))
    assert np.allclose(five.values[j], three.values, rtol=1e-4)
    assert np.allclose(five.ci_low[j], three.ci_low, rtol=1e-3)
    assert np.allclose(five.ci_high[j], three.ci_high, rtol=1e-3)
    for p in STRETCH:
        k = five.paths.index(p)
        assert np.isnan(five.ci_low[k]) and np.isnan(five.ci_high[k])
    assert any("unidentifiable" in w for w in five.warnings)


def test_an_interval_never_leaves_the_bounds(tmp_path):
    """The 6 bar rows alone (five): strain_scale's linearised interval value +- q std reaches below
    0 % (a contraction scale below zero means nothing), the reported one lies within its bounds,
    made on the logit of its place between them, and holds the estimate."""
    table = _table(tmp_path, lambda d: (d["contraction [%]"] >= 0) & (d["pressure [bar gauge]"] == 6))
    res = fit(_spec(tmp_path, table, THREE))
    k = res.paths.index("muscle_force.strain_scale")
    assert res.values[k] - res.quantile * res.std[k] < 0.0
    lo, hi = 0.2e-2, 20e-2
    assert lo <= res.ci_low[k] < res.values[k] < res.ci_high[k] <= hi
    assert res.interval_method[k].startswith("logit")
    for j in range(len(res.paths)):
        prm = res.spec.parameters[j]
        assert prm.lower <= res.ci_low[j] and res.ci_high[j] <= prm.upper


def test_correlated_residuals_widen_the_intervals_by_their_effective_points(tmp_path):
    """A trace whose error is one slow wave (AR(1) with coefficient 0.9: lag-1 autocorrelation
    0.9, effective points (1 - 0.9)/(1 + 0.9) of the samples) gives intervals wider than the same
    fit believes for white noise of the same size, by about sqrt((1 + 0.9)/(1 - 0.9)) = 4.4."""
    import frogsim
    from fit_helpers import P_ATM, write_rig
    write_rig(tmp_path)
    r = frogsim.simulate(frogsim.load_scenario(tmp_path / "rig.toml"))
    p = (r.muscle_pressure("hip") - P_ATM) / 1e5
    rng = np.random.default_rng(4)
    white = rng.normal(0.0, 0.02, p.size)
    ar = np.zeros(p.size)
    for i in range(1, p.size):
        ar[i] = 0.9 * ar[i - 1] + np.sqrt(1 - 0.81) * white[i]
    out = {}
    for name, err in (("white", white), ("ar", ar)):
        pd.DataFrame({"time [s]": r.t, "hip pressure [bar gauge]": p + err}).to_csv(tmp_path / f"{name}.csv",
                                                                                     index=False)
        out[name] = fit({"base_dir": str(tmp_path), "scenario": "rig.toml", "starts": 1, "noise": "0.02 bar",
                         "experiments": [{"trace": f"{name}.csv"}],
                         "parameters": {"valves.charge.sonic_conductance": {"min": "0.1 L/(s*bar)", "max": "1 L/(s*bar)",
                                                                            "start": "0.4 L/(s*bar)"}}})
    assert not out["white"].residual_correlation["correlated"]
    rc = out["ar"].residual_correlation
    assert rc["correlated"] and rc["lag1_autocorrelation"] > 0.8
    ratio = (out["ar"].ci_high - out["ar"].ci_low)[0] / (out["white"].ci_high - out["white"].ci_low)[0]
    assert 2.5 < ratio < 8.0, ratio


def test_summary_names_its_inputs_relative_to_the_spec(tmp_path):
    (tmp_path / "data").mkdir()
    d = pd.read_csv(FESTO)
    d[d["contraction [%]"] >= 0].to_csv(tmp_path / "data" / "t.csv", index=False)
    (tmp_path / "FIT.toml").write_text(f'scenario = "{RIG}"\nstarts = 1\n[[force_tables]]\ntable = "data/t.csv"\n'
                                       'muscle = "hip"\nnoise = "50 N"\n[parameters]\n'
                                       '"muscle_force.force_scale" = { min = "0 N", max = "1000 N", start = "100 N" }\n')
    assert main(["fit", str(tmp_path / "FIT.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["fit_spec"] == "FIT.toml" and s["force_tables"][0]["table"] == "data/t.csv"
    assert s["parameters"]["muscle_force.force_scale"]["identifiable"] is True
