"""The paper's studies: figures the paper states (Sec. 4.2-4.3) and the trends of Figs. 15-17."""
import math

import numpy as np
import pytest

from frogsim.studies import STUDIES


@pytest.fixture(scope="module")
def summaries(study):
    out = {}
    for name in STUDIES:
        out.update(study(name).summary)
    return out


def test_aeration_volumes_match_paper(summaries):
    # paper Sec. 4.2: 0.455 L (hip), 0.401 L (knee and ankle) at standard state; acceptance: 5 %
    aer = summaries["aeration_volume_L"]
    assert aer["hip"] == pytest.approx(0.455, rel=0.05)
    assert aer["knee"] == pytest.approx(0.401, rel=0.05)
    assert aer["ankle"] == pytest.approx(0.401, rel=0.05)


def test_paper_branch_limit(summaries):
    # paper Sec. 4.3: "saturation for each branch pipe ... set at 45 L/min"; Eq. (9) on a 4 mm bore
    # at the speed of sound over six branches gives 43.1 L/min; acceptance window 42-46 L/min
    assert 42.0 <= summaries["branch_saturation_L_per_min"] <= 46.0


def test_unsaturated_rise_under_0p2s_and_saturated_clearly_slower(summaries):
    sweep = summaries["source_pressure_sweep"]
    uns = {e["source_pressure_bar_gauge"]: e for e in sweep["unsaturated"]}
    sat = {e["source_pressure_bar_gauge"]: e for e in sweep["saturated"]}
    # paper Sec. 4.3: without saturation "the pressure response ... fell within 0.2 s"
    assert uns[6]["rise_time_90_s"] < 0.2
    # with saturation clearly slower: at least twice as long
    assert sat[6]["rise_time_90_s"] > 2 * uns[6]["rise_time_90_s"]


def test_fig15_final_pressure_rises_with_source_pressure(summaries):
    for label in ("saturated", "unsaturated"):
        entries = sorted(summaries["source_pressure_sweep"][label],
                         key=lambda e: e["source_pressure_bar_gauge"])
        finals = [e["final_muscle_pressure_bar_gauge"] for e in entries]
        assert all(b > a for a, b in zip(finals, finals[1:])), finals
        # the muscle cannot end above its source
        for e in entries:
            assert e["final_muscle_pressure_bar_gauge"] < e["source_pressure_bar_gauge"]


def test_fig15_saturated_curves_identical_before_balance(study):
    # paper Sec. 4.3: under saturation "the pressurizing process was identical before the balanced
    # state": the flow is capped by the branch limit, not by the source pressure
    d = study("fig15").table
    early = d["time [s]"] <= 0.1
    p3 = d.loc[early, "hip pressure 3 bar source saturated [bar gauge]"].to_numpy()
    p6 = d.loc[early, "hip pressure 6 bar source saturated [bar gauge]"].to_numpy()
    assert np.max(np.abs(p3 - p6)) < 0.01 * p6.max()


def test_fig16_rise_time_grows_with_muscle_volume(summaries):
    entries = sorted(summaries["muscle_volume_sweep"], key=lambda e: e["volume_constant_percent"])
    for key in ("rise_time_90_s", "unsaturated_rise_time_90_s", "muscle_volume_cm3"):
        vals = [e[key] for e in entries]
        assert all(b > a for a, b in zip(vals, vals[1:])), (key, vals)


def test_fig17_rise_time_falls_as_limit_rises(summaries):
    entries = sorted(summaries["saturation_sweep"], key=lambda e: e["branch_limit_L_per_min"])
    # 15 L/min for the 1 s pressurise passes at most 0.25 L standard, short of the 0.455 L the hip
    # takes to fill (paper Sec. 4.2): its 90 % rise is not reached, and says so
    assert entries[0]["branch_limit_L_per_min"] == 15
    assert entries[0]["rise_time_90_s"] is None
    assert entries[0]["rise_time_90_reason"].startswith("not reached before the charge valve closed")
    rises = [e["rise_time_90_s"] for e in entries[1:]]
    assert all(b < a for a, b in zip(rises, rises[1:])), rises


def test_source_drop_matches_adiabatic_mass_balance(summaries):
    # Eq. (2) integrated with Eq. (3): a rigid adiabatic source that gives away mass dm follows
    # p/p0 = (m/m0)^k. Six muscles take 2 x 0.455 + 4 x 0.401 L standard (the paper's aeration
    # volumes), i.e. dm = rho_ref * 2.514 L from m0 = p0 V/(R T0) in the 4 L source at 7.013 bar.
    R, T0, V, k = 287.0, 293.15, 4e-3, 1.4
    p0 = 6e5 + 101325.0
    rho_ref = 1e5 / (R * 293.15)
    m0 = p0 * V / (R * T0)
    dm = rho_ref * (2 * 0.455 + 4 * 0.401) * 1e-3
    expected_drop = (p0 - p0 * ((m0 - dm) / m0) ** k) / 1e5
    assert summaries["source_chamber"]["pressure_drop_bar"] == pytest.approx(expected_drop, rel=0.03)


def test_tube_modes_physical_exceeds_eq9_and_is_shared(summaries):
    t = summaries["tube_modes"]
    limit = summaries["branch_saturation_L_per_min"]
    # paper mode: each branch is capped at Eq. (9)'s share whether one or six are open
    assert t["paper"]["one_branch_L_per_min"] == pytest.approx(limit, rel=1e-3)
    assert t["paper"]["six_branches_L_per_min"] == pytest.approx(limit, rel=1e-3)
    # physical mode, one branch: the valve is the restriction. MHJ9 choked flow (paper Sec. 3.3):
    # C p1 = 0.4 L/(s bar) x 7.013 bar = 168.3 L/min; the tube in series takes a little of it
    assert 0.9 * 168.3 < t["physical"]["one_branch_L_per_min"] <= 168.3 * 1.001
    # six branches share one 4 mm tube: less per branch than one alone, still above Eq. (9)
    assert t["physical"]["six_branches_L_per_min"] < t["physical"]["one_branch_L_per_min"]
    assert t["physical"]["six_branches_L_per_min"] > 2 * limit


def _documented_columns() -> dict:
    """study -> (the columns docs/metrics.md's study table names, whether it elides others with
    "...")."""
    import re
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "docs" / "metrics.md").read_text()
    rows = {}
    for line in text.splitlines():
        m = re.match(r"\| `([a-z0-9-]+)` \| (.*) \|$", line)
        if m:
            named, dots, _ = m.group(2).partition("...")
            rows[m.group(1)] = (re.findall(r"`([^`]+)`", named), bool(dots))
    return rows


def test_every_study_is_finite_and_documented(tmp_path, study):
    """Contract over the registry: deterministic (the session's run and a fresh one), finite, with
    a title, a table and a drawing; documented: named in the README, its CSV's columns those of its
    row in docs/metrics.md's study table (all of them, unless the row elides some with "..."),
    each written 'name [unit]' in the one convention."""
    from pathlib import Path

    from conftest import assert_unit_headers
    from frogsim.studies.registry import write_table
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    documented = _documented_columns()
    computed = study
    for name, study in STUDIES.items():
        assert study.title
        a = computed(name)
        b = study.compute()
        assert len(a.table) > 0
        assert f"`{name}`" in readme, f"{name} is not named in README.md"
        assert name in documented, f"{name} has no row in docs/metrics.md's study table"
        columns, elided = documented[name]
        write_table(name, a, tmp_path)
        written = list(assert_unit_headers(tmp_path / f"{name}.csv").columns)
        assert [c for c in written if c in columns] == columns, (name, columns, written)
        assert elided or written == columns, (name, written)
        num = a.table.select_dtypes("number")
        # NaN only for a rise time not reached, where the share of the rise reached says so
        for col in num.columns:
            bad = ~np.isfinite(num[col].to_numpy())
            if bad.any():
                assert col.endswith("rise time 90 % [s]") and "hip rise reached [%]" in num, (name, col)
                assert np.all(num["hip rise reached [%]"].to_numpy()[bad] < 90), (name, col)
        num = num.to_numpy()
        assert np.array_equal(num, b.table.select_dtypes("number").to_numpy(), equal_nan=True), name

        def finite(x):
            if isinstance(x, dict):
                return all(finite(v) for v in x.values())
            if isinstance(x, list):
                return all(finite(v) for v in x)
            return not isinstance(x, float) or math.isfinite(x)
        assert finite(a.summary), name
        png = tmp_path / f"{name}.png"
        study.draw(a, str(png))
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
