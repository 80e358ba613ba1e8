"""docs/fitting.md's numbers from runs are the code's: the published loop's fit (section 7, "A
published loop") from the hysteresis study, which runs the page's command, and the loop height at
rest length from Hunt et al.'s constants. The fits' printed outputs are compared with runs of their
commands in tests/test_doc_blocks.py."""
from __future__ import annotations

import pytest
from page_numbers import NUM, ROOT, check, page, section, table_rows

DOC = page("fitting.md")
TANK = ROOT / "examples" / "fit" / "tank-heat"


def test_the_published_loops_fit(study):
    loop = study("hysteresis").summary["hysteresis"]["published_loop"]
    assert loop["fit"] == "frogsim fit examples/fit/hysteresis/FIT.toml"
    rows = table_rows(DOC, "`frogsim fit examples/fit/hysteresis/FIT.toml --out hysteresis-fit` gives")
    lo, hi = loop["slip_per_pressure_ci95_N_per_bar"]
    check(rows["`slip_per_pressure`"][1], [("^" + NUM + " N/bar,", loop["slip_per_pressure_N_per_bar"]),
                                           ("interval " + NUM + "-", lo), ("-" + NUM + " N/bar$", hi)])
    residual = next(v for k, v in rows.items() if k.startswith("force residual"))
    check(residual[0], [(r"force residual, " + NUM + " rows", loop["rows"])])
    check(residual[1], [("^" + NUM + " N rms", loop["force_rms_error_N"]),
                        (r"largest force " + NUM + " N", loop["largest_force_N"])])
    check(rows["braid angle"][1], [("^" + NUM + " deg$", loop["braid_angle_deg"])])
    check(residual[1], [("worst " + NUM + " N", loop["worst_force_error_N"])])
    at = loop["worst_force_error_at"]          # "at rest length at 6 bar": no contraction, the top pressure
    assert "at rest length at 6 bar" in residual[1]
    assert at["contraction_percent"] == 0.0 and at["pressure_bar_gauge"] == 6.0, at
    height = next(v for k, v in rows.items() if k.startswith("loop height"))
    check(height[1], [("^" + NUM + " N fitted", loop["mean_height_fitted_N"]),
                      (NUM + " N published", loop["mean_height_published_N"])])
    text = " ".join(section(DOC, "The mean height matches").split())
    check(text, [(r"\(" + NUM + " N rms apart", loop["height_rms_difference_N"])])
    # the prose above the table: the rows of the example's table
    above = " ".join(section(DOC, "**A published loop: `examples/fit/hysteresis`.**").split())
    check(above, [(r"direction column \(" + NUM + " rows\\)", loop["rows"]),
                  (r"muscle pulls " + NUM + " N at 6 bar", loop["largest_force_N"])])


def test_hunts_loop_height_at_rest_length():
    from frogsim.components import hunt2017 as h
    text = " ".join(section(DOC, "The mean height matches").split())
    check(text, [(r"c6/c5 = " + NUM + " N", h.C6 / h.C5)])


@pytest.fixture(scope="module")
def vessel_fit(tmp_path_factory):
    """vessel_fit(run) -> summary.json of `frogsim fit examples/fit/tank-heat/FIT-RUN.toml`, the
    command the page gives, run once for this file."""
    import json

    from frogsim.cli import main
    done = {}

    def get(run):
        if run not in done:
            out = tmp_path_factory.mktemp(run) / "fit"
            assert main(["fit", str(TANK / f"FIT-{run}.toml"), "--out", str(out), "--quiet"]) == 0
            done[run] = json.loads((out / "summary.json").read_text())
        return done[run]
    return get


@pytest.mark.parametrize("run", ["discharge", "filling"])
def test_the_vessel_fits_table(run, vessel_fit):
    """Section 10's table, each row from the run of the command the page gives (`frogsim fit
    examples/fit/tank-heat/FIT-RUN.toml`): h and C with their 95 % intervals, the fitted rms of
    pressure and temperature (summary.json), and the temperature trace's range."""
    import pandas as pd

    s = vessel_fit(run)
    h = s["parameters"]["source.heat_transfer_coefficient"]
    c = s["parameters"]["valves.charge.sonic_conductance"]
    sig = {k: v for e in s["experiments"] for k, v in e["signals"].items()}
    temp = pd.read_csv(TANK / f"{run}-temperature.csv")
    tcol = next(col for col in temp.columns if col.startswith("source temperature"))
    row = table_rows(DOC, "| run | h [W/(m² K)], 95 % |")[run]
    check(row[1], [("^" + NUM + " ", h["value_si"]), (r"\(" + NUM + " ", h["ci_low_si"]),
                   (r"\.\. " + NUM + r"\)", h["ci_high_si"])])
    check(row[2], [("^" + NUM + " ", c["value_si"] * 1e8), (r"\(" + NUM + " ", c["ci_low_si"] * 1e8),
                   (r"\.\. " + NUM + r"\)", c["ci_high_si"] * 1e8)])           # m^3/(s Pa) -> L/(s bar)
    check(row[3], [("^" + NUM + " bar$", sig["source pressure"]["rms_residual_fitted_Pa"] / 1e5)])
    check(row[4], [("^" + NUM + " K$", sig["source temperature"]["rms_residual_fitted_K"])])
    check(row[5], [("^" + NUM + " K$", float(temp[tcol].max() - temp[tcol].min()))])


def test_the_vessel_whole_runs_prose(vessel_fit):
    """Section 10's prose under the whole runs' table: how far the residuals stand above the stated
    noise (the fits' warnings), the measured and the fitted model's temperatures (`frogsim.simulate`
    of each run at its fitted h and C, and the filling with h = 0), the effective discharge
    coefficient the fitted C points to (the ideal nozzle's C from the formula the page gives, with
    air's R, k and the ISO 8778 reference state), and the whole-run h the last paragraph rounds."""
    import math
    import re

    import numpy as np
    import pandas as pd

    import frogsim
    from conftest import K_AIR, R_AIR, RHO_REF, T_REF
    from frogsim.fit import load_fit_spec
    text = " ".join(section(DOC, "**Whole runs**", "**After the flow**").split())
    fits = {run: vessel_fit(run) for run in ("discharge", "filling")}
    times = {}
    for run, s in fits.items():
        warned = next(w for w in s["warnings"] if "x the stated noise" in w)
        times[run] = float(re.match(r"the residuals are ([\d.]+) x the stated noise", warned).group(1))
    check(text, [(r"residuals are " + NUM + " and", times["discharge"]),
                 (r"residuals are \d+ and " + NUM + " times the assumed noise", times["filling"])])
    model, measured = {}, {}
    for run, s in fits.items():
        values = {p: s["parameters"][p]["value_si"] for p in ("source.heat_transfer_coefficient",
                                                              "valves.charge.sonic_conductance")}
        scenario = load_fit_spec(TANK / f"FIT-{run}.toml").experiments[1].scenario     # the temperature's run
        for h in ("fitted", "none"):
            changes = values if h == "fitted" else {**values, "source.heat_transfer_coefficient": 0.0}
            df = frogsim.simulate(scenario.replace(changes)).to_dataframe()
            model[run, h] = (df["time_s"].to_numpy(), df["source_temperature_K"].to_numpy())
        data = pd.read_csv(TANK / f"{run}-temperature.csv")
        measured[run] = (data.iloc[:, 0].to_numpy(), data.iloc[:, 1].to_numpy())
    t, T = measured["discharge"]
    tm, Tm = model["discharge", "fitted"]
    check(text, [(r"\(minimum " + NUM + " K at", T.min()), (r"K at " + NUM + " s; the fitted", t[T.argmin()]),
                 (r"the fitted model " + NUM + " K at", Tm.min()), (r"model [\d.]+ K at " + NUM + r" s\)", tm[Tm.argmin()]),
                 (r"\(discharge: " + NUM + " K at", T[-1]), (r"discharge: [\d.]+ K at " + NUM + " s,", t[-1]),
                 (r"s, the model " + NUM + r" K\)", np.interp(t[-1], tm, Tm))])
    check(text, [(r"\(peak " + NUM + " K;", measured["filling"][1].max()),
                 (r"; the model " + NUM + " K, and adiabatic", model["filling", "fitted"][1].max()),
                 (r"would reach " + NUM + " K, the same model with h = 0", model["filling", "none"][1].max())])

    def nozzle(d_mm, cd):
        """C [L/(s bar)] of an ideal nozzle, the page's formula."""
        psi = math.sqrt(K_AIR / R_AIR) * (2 / (K_AIR + 1)) ** ((K_AIR + 1) / (2 * (K_AIR - 1)))
        return cd * math.pi / 4 * (d_mm * 1e-3) ** 2 * psi / (RHO_REF * math.sqrt(T_REF)) * 1e8
    model_text = " ".join(section(DOC, "**The model** (`vessel.toml`)").split())
    check(model_text, [(r"\): " + NUM + r" L/\(s·bar\) for 2.1 mm", nozzle(2.1, 0.84)),
                       (r", " + NUM + r" L/\(s·bar\) for 2.71 mm", nozzle(2.71, 0.84))])
    c = np.mean([s["parameters"]["valves.charge.sonic_conductance"]["value_si"] * 1e8 for s in fits.values()])
    check(text, [(r"effective C_d of about " + NUM, c / nozzle(2.71, 1.0)),
                 (r"2.1 mm would need C_d of about " + NUM, c / nozzle(2.1, 1.0)),
                 (r"C is at most " + NUM + r" L/\(s·bar\) at C_d = 1", nozzle(2.1, 1.0))])
    tail = " ".join(section(DOC, "What this means for the robot's parameter set").split())
    check(tail, [(r"\(about " + NUM + r" W/\(m² K\) fitted over a whole run",
                  fits["discharge"]["parameters"]["source.heat_transfer_coefficient"]["value_si"])])
