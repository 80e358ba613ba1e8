"""docs/fitting.md's numbers from runs are the code's: the published loop's fit (section 7, "A
published loop") from the hysteresis study, which runs the page's command, and the loop height at
rest length from Hunt et al.'s constants. The fits' printed outputs are compared with runs of their
commands in tests/test_doc_blocks.py."""
from __future__ import annotations

import pytest
from page_numbers import NUM, check, page, section, table_rows

DOC = page("fitting.md")


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


@pytest.mark.parametrize("run", ["discharge", "filling"])
def test_the_vessel_fits_table(run, tmp_path):
    """Section 10's table, each row from the run of the command the page gives (`frogsim fit
    examples/fit/tank-heat/FIT-RUN.toml`): h and C with their 95 % intervals, the fitted rms of
    pressure and temperature (summary.json), and the temperature trace's range."""
    import json

    import pandas as pd

    from frogsim.cli import main
    from page_numbers import ROOT
    out = tmp_path / "fit"
    assert main(["fit", str(ROOT / "examples" / "fit" / "tank-heat" / f"FIT-{run}.toml"), "--out", str(out),
                 "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    h = s["parameters"]["source.heat_transfer_coefficient"]
    c = s["parameters"]["valves.charge.sonic_conductance"]
    sig = {k: v for e in s["experiments"] for k, v in e["signals"].items()}
    temp = pd.read_csv(ROOT / "examples" / "fit" / "tank-heat" / f"{run}-temperature.csv")
    tcol = next(col for col in temp.columns if col.startswith("source temperature"))
    row = table_rows(DOC, "| run | h [W/(m² K)], 95 % |")[run]
    check(row[1], [("^" + NUM + " ", h["value_si"]), (r"\(" + NUM + " ", h["ci_low_si"]),
                   (r"\.\. " + NUM + r"\)", h["ci_high_si"])])
    check(row[2], [("^" + NUM + " ", c["value_si"] * 1e8), (r"\(" + NUM + " ", c["ci_low_si"] * 1e8),
                   (r"\.\. " + NUM + r"\)", c["ci_high_si"] * 1e8)])           # m^3/(s Pa) -> L/(s bar)
    check(row[3], [("^" + NUM + " bar$", sig["source pressure"]["rms_residual_fitted_Pa"] / 1e5)])
    check(row[4], [("^" + NUM + " K$", sig["source temperature"]["rms_residual_fitted_K"])])
    check(row[5], [("^" + NUM + " K$", float(temp[tcol].max() - temp[tcol].min()))])
