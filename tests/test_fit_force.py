"""Fitting the muscle force law to force-contraction tables: recovery of known constants, interval
coverage, FESTO's data, bad tables refused, and the outputs.

The tables are made here from constants chosen by the test (evaluated with the physics module's
law directly) or copied from FESTO's data; nothing expected is taken from the fit's own output.
"""
from __future__ import annotations

import json
import math
import re

import numpy as np
import pandas as pd
import pytest

from frogsim.cli import main
from frogsim.fit import fit
from frogsim.physics.muscle import braid_parameters
from frogsim.physics.muscle_force import MODEL_DMSP20, muscle_force

from fit_helpers import write_rig

NAMES = ("force_scale", "strain_scale", "stiffness", "stretch_stiffness", "stretch_quadratic")
#: fan2017 has 141.6 N, 2.155 %, 552.9 N, 6302 N, 229100 N
TRUE = dict(force_scale=120.0, strain_scale=0.03, stiffness=700.0, stretch_stiffness=5000.0,
            stretch_quadratic=300000.0)
BOUNDS = {
    "muscle_force.force_scale": {"min": "0 N", "max": "1000 N", "start": "150 N"},
    "muscle_force.strain_scale": {"min": "0.2 %", "max": "20 %", "start": "2 %"},
    "muscle_force.stiffness": {"min": "0 N", "max": "5000 N", "start": "500 N"},
    "muscle_force.stretch_stiffness": {"min": "0 N", "max": "50000 N", "start": "6000 N"},
    "muscle_force.stretch_quadratic": {"min": "0 N", "max": "1000000 N", "start": "200000 N"},
}
D0, THETA0, L0 = 0.020, math.radians(25.3), 0.180      # the fan2017 hip muscle's braid (DMSP-20)


def law(p_gauge: float, eps: float, c: dict) -> float:
    b0, n = braid_parameters(L0, D0, THETA0)
    return muscle_force(MODEL_DMSP20, p_gauge, L0 * (1 - eps), L0, b0, n, *(c[k] for k in NAMES))


def truth_rows():
    """(bar, contraction, force) at 0-6 bar over -4..24 %, where the true law pulls > 30 N."""
    rows = []
    for bar in range(7):
        for eps in np.arange(-0.04, 0.245, 0.02):
            f = law(bar * 1e5, float(eps), TRUE)
            if f > 30.0:
                rows.append((bar, float(eps), f))
    return rows


def write_table(path, rows, noise_n=0.0, seed=0):
    rng = np.random.default_rng(seed)
    bar, eps, f = (np.array(v) for v in zip(*rows))
    f = f + rng.normal(0.0, noise_n, f.size) * (noise_n > 0)
    pd.DataFrame({"pressure [bar gauge]": bar, "contraction [%]": eps * 100, "force [N]": f}).to_csv(
        path, index=False, float_format="%.12g")
    return path


def spec(folder, table, noise="20 N", **extra):
    return {"base_dir": str(folder), "scenario": "rig.toml",
            "force_tables": [{"table": table, "muscle": "hip", "noise": noise}], "parameters": BOUNDS, **extra}


@pytest.fixture(scope="module")
def rig_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("force")
    write_rig(folder)
    return folder


def test_zero_noise_recovers_the_five_constants(rig_dir):
    write_table(rig_dir / "exact.csv", truth_rows())
    res = fit(spec(rig_dir, "exact.csv", starts=2))
    truth = np.array([TRUE[k] for k in NAMES])
    err = np.abs(res.values - truth) / truth
    print("relative errors, zero noise:", dict(zip(NAMES, err)))
    assert np.all(err < 1e-4), err
    assert res.model_runs == 0            # a force table needs no pneumatic run


SEEDS = 300


def test_intervals_are_neither_too_narrow_nor_too_wide_over_300_seeds(rig_dir):
    """The interval machinery's statistics, on the force law (no pneumatic run: 300 fits in about
    15 s), checked from both sides with power to spare.

    Too narrow, against the truth: each 95 % interval holds the true constant in at least 272 of
    the 300 seeds. A correct interval fails that with probability P(Bin(300, 0.95) < 272) = 0.06 %
    per constant (0.3 % for the five); one of 80 % coverage passes it with P(Bin(300, 0.8) >= 272)
    = 4e-7, one of 90 % with 40 %.

    Too wide (or too narrow), against the width a correct interval has: the standard deviation of
    the 300 estimates equals the standard error the interval claims, its half-width over the
    Student-t quantile for n - p = 75 - 5 degrees of freedom (computed here, not read from the
    fit), to within 0.85..1.18. For a correct interval the sample standard deviation of 300
    estimates falls outside that with probability P(chi2_299 < 0.85^2 * 299) +
    P(chi2_299 > 1.18^2 * 299) = 1e-4 per constant; an interval 3 times too wide gives 1/3, one of
    80 % coverage (half-width 1.29 instead of 1.99 standard errors) 1.54.

    The noise is 5 N, where the law is nearly linear over the estimates' spread, so that a correct
    linearised interval has its nominal 95 %."""
    from scipy import stats
    rows = truth_rows()
    truth = np.array([TRUE[k] for k in NAMES])
    q = stats.t.ppf(0.975, len(rows) - len(NAMES))
    covered = np.zeros(len(NAMES), dtype=int)
    est, se = [], []
    for seed in range(SEEDS):
        write_table(rig_dir / f"noisy-{seed}.csv", rows, noise_n=5.0, seed=100 + seed)
        res = fit(spec(rig_dir, f"noisy-{seed}.csv", noise="5 N", starts=1))
        covered += (res.ci_low <= truth) & (truth <= res.ci_high)
        est.append(res.values)
        se.append((res.ci_high - res.ci_low) / (2 * q))
    ratio = np.std(est, axis=0, ddof=1) / np.mean(se, axis=0)
    print(f"coverage of the 95 % intervals in {SEEDS} seeds:", dict(zip(NAMES, covered)))
    print("spread of the estimates / claimed standard error:", dict(zip(NAMES, ratio)))
    assert len(rows) == 75
    assert np.all(covered >= 272), dict(zip(NAMES, covered))
    assert np.all((0.85 < ratio) & (ratio < 1.18)), dict(zip(NAMES, ratio))
    # docs/fitting.md quotes the counts, in NAMES' order
    import re
    from pathlib import Path
    page = " ".join((Path(__file__).resolve().parents[1] / "docs" / "fitting.md").read_text().split())
    m = re.search(r"over 300 seeds: (\d+), (\d+), (\d+), (\d+) and (\d+) of 300 \(" + ", ".join(NAMES[:-1])
                  + " and " + NAMES[-1] + r"\)", page)
    assert m, "docs/fitting.md no longer quotes the force law's coverage over 300 seeds"
    assert [str(c) for c in covered] == list(m.groups())


def test_fit_to_festo_rows_matches_the_held_out_rows(rig_dir):
    # FESTO's DMSP-20 data (tabulated in frogsim.components.dmsp20, cited there): fit to the 1, 3
    # and 5 bar rows with each row's noise max(10 % of the force, 50 N), then check the law against
    # the 2, 4, 6 bar rows it has not seen, within the same 10 % or 50 N over 0-20 % contraction
    from frogsim.components.dmsp20 import REFERENCE
    rows = [(p / 1e5, e, f) for p in (1e5, 3e5, 5e5) for e, f in zip(*REFERENCE[p])]
    write_table(rig_dir / "festo.csv", rows)
    res = fit({**spec(rig_dir, "festo.csv", noise="50 N"), "force_tables": [
        {"table": "festo.csv", "muscle": "hip", "noise": "50 N", "relative_noise": 0.1}]})
    c = dict(zip(NAMES, res.values))
    held_out = {2: ((0.01, 0.05, 0.12, 0.155), (429, 240, 112, 8.7)),
                4: ((0.0, 0.01, 0.04, 0.09, 0.16), (1012, 926, 737, 518, 271)),
                6: ((0.0, 0.035, 0.065, 0.11), (1515, 1228, 1040, 791))}
    for bar, (eps, forces) in held_out.items():
        for e, f_ref in zip(eps, forces):
            assert abs(law(bar * 1e5, e, c) - f_ref) <= max(0.1 * f_ref, 50.0), (bar, e, f_ref)
    negative = sum(int(np.sum(np.array(REFERENCE[p][1]) < 0)) for p in (1e5, 3e5, 5e5))
    assert any(f"{negative} row(s) with a negative force" in w for w in res.warnings), res.warnings


GOOD = "pressure [bar gauge],contraction [%],force [N]\n1,0,250\n3,5,500\n5,10,700\n"


@pytest.mark.parametrize("text, expect", [
    ("pressure [bar gauge],contraction [%],force [N]\n1,0,250\n3,x,500\n", ["'contraction [%]'", "not numbers"]),
    ("pressure [bar gauge],contraction [%],force [N]\n1,0,250\n3,5,nan\n", ["'force [N]'", "NaN"]),
    ("pressure [bar gauge],contraction,force [N]\n1,0,250\n3,5,500\n", ["'contraction'", "no unit"]),
    ("pressure [bar gauge],contraction [%],force [N]\n1,0,250\n-0.5,5,500\n",
     ["'pressure [bar gauge]'", "negative gauge pressure"]),
    ("pressure [bar gauge],contraction [%],force [N]\n1,0,250\n3,100,500\n",
     ["'contraction [%]'", "below 100 %"]),
    ("pressure [bar],contraction [%],force [N]\n1,0,250\n", ["'pressure [bar]'", "gauge or abs"]),
    ("pressure [bar gauge],contraction [%],force [bar]\n1,0,250\n", ["'force [bar]'", "not a force unit"]),
])
def test_bad_tables_exit_2_in_one_line_and_write_nothing(tmp_path, capsys, text, expect):
    write_rig(tmp_path)
    (tmp_path / "f.csv").write_text(text)
    p = tmp_path / "FIT.toml"
    p.write_text('scenario = "rig.toml"\n[[force_tables]]\ntable = "f.csv"\n[parameters]\n'
                 '"muscle_force.force_scale" = { min = "0 N", max = "1000 N" }\n')
    out = tmp_path / "out"
    assert main(["fit", str(p), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("frogsim: error: ") and "\n" not in err, err
    for part in ["f.csv", *expect]:
        assert part in err, err
    assert not out.exists()


def test_cli_outputs_worst_error_per_pressure_and_the_fitted_law(rig_dir, tmp_path, capsys):
    write_table(rig_dir / "cli.csv", truth_rows(), noise_n=20.0, seed=7)
    p = rig_dir / "FIT-force.toml"
    p.write_text('scenario = "rig.toml"\nstarts = 1\n[[force_tables]]\nname = "bench"\ntable = "cli.csv"\n'
                 'noise = "20 N"\n[parameters]\n'
                 + "".join(f'"{k}" = {{ min = "{v["min"]}", max = "{v["max"]}", start = "{v["start"]}" }}\n'
                           for k, v in BOUNDS.items()))
    out = tmp_path / "out"
    assert main(["fit", str(p), "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    (table,) = s["force_tables"]
    assert [w["pressure_Pa_gauge"] for w in table["per_pressure"]] == [k * 1e5 for k in range(7)]
    rows = truth_rows()
    for w in table["per_pressure"]:
        assert w["rows"] == sum(1 for r in rows if r[0] * 1e5 == w["pressure_Pa_gauge"])
        # 20 N noise: the worst of a few rows lies within a few sigma, and it is where the table has a row
        assert 0 < w["worst_abs_error_N"] < 5 * 20.0
        assert any(abs(r[1] - w["worst_at_contraction"]) < 1e-9 for r in rows)
    assert abs(s["parameters"]["muscle_force.force_scale"]["value_si"] - TRUE["force_scale"]) < 30
    text = (out / "fitted-parameters.toml").read_text()
    assert re.search(r'stiffness = \{ value = "[0-9.e+]+ N", source = "fitted to cli.csv on ', text)
    assert (out / "force-1-bench.png").read_bytes().startswith(b"\x89PNG")
    page = (out / "report.html").read_text()
    assert "Force law against the force tables" in page and "worst |error| [N]" in page
    # the fitted parameter set loads with the robot's force law
    import frogsim
    from frogsim.fit.force import base_law
    sc = frogsim.load_scenario({"name": "x", "parameters": str(out / "fitted-parameters.toml"), "duration": "0.5 s",
                                "muscles": {"hip": {"type": "hip", "program": {"pressurise": "0.25 s",
                                                                               "release": "0.25 s"},
                                                        "motion": {"kind": "constant"}}}})
    assert base_law(sc).stiffness == pytest.approx(s["parameters"]["muscle_force.stiffness"]["value_si"], rel=1e-5)


def test_profile_interval_matches_the_jacobian_interval_on_a_linear_case(rig_dir):
    # force_scale and stiffness enter the law linearly (where it pulls): the profile interval of
    # each must then equal the linearised one; strain_scale does not, and its profile interval
    # must still contain the truth
    write_table(rig_dir / "lin.csv", truth_rows(), noise_n=20.0, seed=3)
    fixed = {k: v for k, v in BOUNDS.items() if k in ("muscle_force.force_scale", "muscle_force.stiffness")}
    s = spec(rig_dir, "lin.csv", starts=1, profile=list(fixed))
    s["parameters"] = fixed
    res = fit(s)
    for j, path in enumerate(res.paths):
        lo, hi = res.profile[path]
        width = res.ci_high[j] - res.ci_low[j]
        assert lo == pytest.approx(res.ci_low[j], abs=1e-3 * width), path
        assert hi == pytest.approx(res.ci_high[j], abs=1e-3 * width), path
    res = fit(spec(rig_dir, "lin.csv", starts=1, profile=["muscle_force.strain_scale"]))
    lo, hi = res.profile["muscle_force.strain_scale"]
    assert lo <= TRUE["strain_scale"] <= hi
    # docs/fitting.md quotes these two intervals (in %, two decimals): they must be this table's
    import re
    from pathlib import Path
    page = " ".join((Path(__file__).resolve().parents[1] / "docs" / "fitting.md").read_text().split())
    m = re.search(r"strain_scale: linearised (\d+\.\d+)\.\.(\d+\.\d+) %, profile (\d+\.\d+)\.\.(\d+\.\d+) %", page)
    assert m, "docs/fitting.md no longer quotes strain_scale's intervals"
    j = res.paths.index("muscle_force.strain_scale")
    got = [f"{100 * x:.2f}" for x in (res.ci_low[j], res.ci_high[j], lo, hi)]
    assert got == list(m.groups()), (got, m.groups())
