"""Every CSV frogsim writes speaks the one header convention, ``name [unit]``
(frogsim.scenario.tables): the studies' CSVs of reproduce, design and control, simulate's
timeseries.csv and compare's CSV here; swim's timeseries.csv and optimize-gait's trials.csv in
tests/test_swim_cli.py and tests/test_optimize_gait.py, whose runs write them."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import assert_unit_headers
from frogsim.cli import main
from frogsim.scenario.tables import split_header
from frogsim.studies import STUDIES, studies_in
from frogsim.studies.registry import write_table


def test_every_study_group_is_covered():
    # the studies of reproduce (paper, robot), design and control are all in the registry walked below
    groups = {s.group for s in STUDIES.values()}
    assert groups == {"paper", "robot", "design", "control"}
    assert sum(len(studies_in(g)) for g in groups) == len(STUDIES)


@pytest.mark.parametrize("name", list(STUDIES))
def test_study_csv_headers_carry_units(name, study, tmp_path):
    data = study(name)
    table = assert_unit_headers(write_table(name, data, tmp_path))
    assert list(table.columns) == list(data.table.columns)
    assert len(table) == len(data.table)
    for col in table.columns:
        if table[col].dtype.kind == "f":          # the numbers as written (8 significant digits)
            assert np.allclose(table[col], data.table[col].astype(float), rtol=1e-7, atol=0, equal_nan=True), col
    units = {split_header(c)[1] for c in table.columns}
    assert units - {""}, name                     # not labels alone


def test_simulate_and_compare_csv_headers(tmp_path):
    run = tmp_path / "run"
    assert main(["simulate", "paper-cycle", "--out", str(run)]) == 0
    t = assert_unit_headers(run / "timeseries.csv")
    assert {"time [s]", "hip_left pressure [bar gauge]", "hip_left charge flow [L/min std]",
            "hip_left charge valve [1 = open]", "pump on [1 = on]"} <= set(t.columns)
    out = tmp_path / "cmp"
    assert main(["compare", str(run), "paper-cycle", "--signal", "hip_left pressure", "--out", str(out)]) == 0
    c = assert_unit_headers(out / "hip_left-pressure.csv")
    assert list(c.columns)[0] == "time [s]" and all(col.endswith(" [bar gauge]") for col in list(c.columns)[1:])


def test_an_old_spelling_is_refused_by_the_check(tmp_path):
    # the check itself: a study column in the old name_unit spelling, an unknown unit, a text column
    for text in ("time_s,hip_pressure_bar_gauge\n0,1\n", "time [s],speed [furlong/fortnight]\n0,1\n",
                 "time [s],hip pressure [bar gauge]\n0,high\n"):
        (tmp_path / "t.csv").write_text(text)
        with pytest.raises(AssertionError):
            assert_unit_headers(tmp_path / "t.csv")


def test_a_study_csv_is_a_compare_input_with_its_units(study, tmp_path):
    # fig13 is the paper-cycle run's hip_left pressure: read back through compare, with its unit,
    # it equals the same scenario run on the spot
    write_table("fig13", study("fig13"), tmp_path)
    out = tmp_path / "cmp"
    assert main(["compare", f"{tmp_path / 'fig13.csv'}:hip pressure", "paper-cycle:hip_left pressure",
                 "--out", str(out)]) == 0
    c = assert_unit_headers(out / "hip-pressure.csv")
    assert list(c.columns) == ["time [s]", "fig13 [bar gauge]", "paper-cycle [bar gauge]"]
    assert np.allclose(c["fig13 [bar gauge]"], c["paper-cycle [bar gauge]"], rtol=1e-7, atol=1e-7)
