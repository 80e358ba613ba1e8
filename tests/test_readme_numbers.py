"""The numbers the README quotes are the code's: each is recomputed from the studies and must
read the same at the precision the README writes it. A change that moves a number fails here;
update the README with it."""
import re
from pathlib import Path

import page_numbers
import pytest

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def table_rows(heading_text: str) -> dict:
    """{first cell: [cells]} of the first Markdown table after the line containing heading_text."""
    return page_numbers.table_rows(README, heading_text)


def same_as_written(text: str, value: float) -> bool:
    """value rounded to the decimals of text equals text."""
    decimals = len(text.split(".")[1]) if "." in text else 0
    return f"{value:.{decimals}f}" == text


NUM = r"(\d+(?:\.\d+)?)"


def check(cell: str, patterns: list) -> None:
    """Each (regex with one number group, value) must match the cell once and read the value."""
    for pattern, value in patterns:
        found = re.findall(pattern, cell)
        assert len(found) == 1, (pattern, cell)
        assert same_as_written(found[0], value), (pattern, found[0], value)


@pytest.fixture(scope="module")
def paper(study):
    out = {}
    for name in ("fig15", "fig14", "aeration", "tube-modes"):
        out.update(study(name).summary)
    return out


def test_measured_table(paper):
    rows = table_rows("Measured with the committed parameter set")
    aer = paper["aeration_volume_L"]
    check(rows["aeration volume hip / knee / ankle"][1],
          [(NUM + r" / [\d.]+ / [\d.]+ L", aer["hip"]), (r"[\d.]+ / " + NUM + r" / [\d.]+ L", aer["knee"]),
           (r"[\d.]+ / [\d.]+ / " + NUM + " L", aer["ankle"])])
    check(rows["Eq. (9) branch limit"][1], [(NUM + " L/min", paper["branch_saturation_L_per_min"])])
    sweep = paper["source_pressure_sweep"]
    sat = next(e for e in sweep["saturated"] if e["source_pressure_bar_gauge"] == 6)
    uns = next(e for e in sweep["unsaturated"] if e["source_pressure_bar_gauge"] == 6)
    check(rows["hip 90 % rise at 6 bar, saturated / unsaturated"][1],
          [(NUM + r" s / ", sat["rise_time_90_s"]), (r" / " + NUM + " s", uns["rise_time_90_s"])])
    check(rows["source drop, six muscles charged at once"][1],
          [(NUM + " bar", paper["source_chamber"]["pressure_drop_bar"])])
    phys = paper["tube_modes"]["physical"]
    check(rows["hip branch flow, physical tube, 1 / 6 branches open"][1],
          [(NUM + r" / \d+ L/min", phys["one_branch_L_per_min"]),
           (r"\d+ / " + NUM + " L/min", phys["six_branches_L_per_min"])])


def test_design_table(study):
    rows = table_rows("| study | question | answer with fan2017 |")
    tubes = study("design-tubes")
    s = tubes.summary["design_tubes"]
    d = tubes.table
    one4 = d[(d["main tube count [-]"] == 1) & (d["main tube inner diameter [mm]"] == 4.0)].set_index("mode")[
        "hip rise time 90 % [s]"]
    check(rows["`design-tubes`"][2], [
        (r"valves alone: " + NUM + " s", s["valve_only_rise_time_90_s"]),
        (r"one 4 mm tube: " + NUM + " s in the paper", one4["paper"]),
        (NUM + " s in the physical mode", one4["physical"]),
        (r"limits from " + NUM + r" mm \(Eq. 9\)", s["valve_limited_from_inner_diameter_mm"]["paper"]["1"]),
        (r"or " + NUM + r" mm \(physical\)", s["valve_limited_from_inner_diameter_mm"]["physical"]["1"]),
    ])
    e = study("design-endurance").summary["design_endurance"]
    check(rows["`design-endurance`"][2], [
        (r"give " + NUM + " full strokes", e["paper_robot"]["strokes_before_short"]),
        (r"sustain " + NUM + " strokes/min", e["paper_robot"]["sustainable_strokes_per_min"]),
        (r"about " + NUM + " L/min", e["pump_for_paper_timing_L_per_min"]["source_4_L"]),
    ])
    v = study("design-valve").summary["design_valve"]
    check(rows["`design-valve`"][2], [
        (r"C\^−" + NUM, -v["rise_time_exponent_in_C"]),
        (r"changes it by " + NUM + " %", 100 * v["rise_time_spread_over_b_at_C_0p4"]),
    ])
    runs = study("design-valve-type").summary["design_valve_type"]["runs"]
    pr, sw, sm = runs["proportional / pid"], runs["switching / bang-bang"], runs["switching / sliding-mode"]
    check(rows["`design-valve-type`"][2], [
        (r"proportional: " + NUM + " /", 1e3 * pr["rise_time_s"]),
        (r"/ " + NUM + " ms rise / fall", 1e3 * pr["fall_time_s"]),
        (r"and " + NUM + " mbar RMS", 1e3 * pr["sine_rms_bar"]),
        (r"against " + NUM + " /", 1e3 * sm["rise_time_s"]),
        (r"/ " + NUM + " ms and", 1e3 * sm["fall_time_s"]),
        (r"and " + NUM + r" mbar \(sliding mode\)", 1e3 * sm["sine_rms_bar"]),
        (NUM + " times the mass", pr["mass_per_muscle_kg"] / sw["mass_per_muscle_kg"]),
        (NUM + " times the price", pr["price_per_muscle_EUR"] / sw["price_per_muscle_EUR"]),
    ])


def test_readme_check_catches_a_moved_number():
    # the check itself: a number one unit off in its last written digit fails
    assert same_as_written("0.081", 0.0806)
    assert not same_as_written("0.078", 0.0806)
    assert not same_as_written("88", 86.9)


def test_force_hysteresis_table(study):
    runs = study("hysteresis").summary["hysteresis"]["runs"]
    rows = table_rows("## Force hysteresis at the joint")
    for key, label in (("off", "off"), ("published", "2.75 N/bar (fan2017-hysteresis)"),
                       ("10_N_per_bar", "10 N/bar (assumed)"), ("25_N_per_bar", "25 N/bar (assumed)")):
        cells, r = rows[label], runs[key]
        check(cells[1], [(NUM + " deg", r["step"]["tracking_error_rms_deg"])])
        check(cells[2], [(NUM + " deg", r["step"]["final_error_deg"])])
        check(cells[3], [(NUM + " deg", r["sine"]["tracking_error_rms_deg"])])
        check(cells[4], [(NUM + " deg", r["sine"]["loop_width_deg"])])
    # the fit to the published loop quoted above the table
    loop = study("hysteresis").summary["hysteresis"]["published_loop"]
    text = README[README.index("## Force hysteresis at the joint"):README.index("| hysteresis |")]
    check(text, [(r"FIT.toml` \(" + NUM + " N/bar", loop["slip_per_pressure_N_per_bar"]),
                 (r"95 % interval " + NUM + "-", loop["slip_per_pressure_ci95_N_per_bar"][0]),
                 (r"95 % interval [\d.]+-" + NUM, loop["slip_per_pressure_ci95_N_per_bar"][1]),
                 (r"the forces to " + NUM + " N rms", loop["force_rms_error_N"]),
                 (r"mean height " + NUM + " N fitted", loop["mean_height_fitted_N"]),
                 (r"against\s+" + NUM + r" N\s+published", loop["mean_height_published_N"])])
    # the paragraph under the table: the loop width without hysteresis, what the published-size loop
    # adds, and the loops' heights at the co-contraction pressure (2 c p_g: every element sliding)
    from frogsim.studies.hysteresis import CO_CONTRACTION_BAR, runs as hysteresis_runs
    slip = {key: c for key, _, c, _ in hysteresis_runs()}
    assert CO_CONTRACTION_BAR == 3.0
    text = " ".join(README[README.index("The loop width is the angle"):README.index("## Wall heat transfer")].split())
    width = {key: r["sine"]["loop_width_deg"] for key, r in runs.items()}
    check(text, [(r"opens it to " + NUM + " deg without hysteresis", width["off"]),
                 (r"loop \(" + NUM + " N high in each muscle at 3 bar", 2 * slip["published"] * 3.0),
                 (r"widens it by " + NUM + " deg", width["published"] - width["off"]),
                 (r"10 N/bar \(" + NUM + r" N\) doubles it", 2 * slip["10_N_per_bar"] * 3.0)])
    assert round(width["10_N_per_bar"] / width["off"]) == 2                   # "doubles it"


def test_heat_table(study):
    rows = table_rows("runs each case both ways and prints")
    runs = study("heat").summary["heat"]["runs"]
    a, h = runs["adiabatic"], runs["heat"]
    check(rows["hip charged to 5.91 bar, held closed 1.7 s: pressure sag"][0],
          [(r"charged to " + NUM + " bar", a["hold_pressure_at_close_bar_gauge"])])
    for key, col, unit in (("hold_pressure_sag_bar", "hip charged to 5.91 bar, held closed 1.7 s: pressure sag", "bar"),
                           ("paper_cycle_air_per_stroke_L_std", "paper cycle: air per stroke (six muscles)", "L std"),
                           ("paper_cycle_hip_temperature_at_1s_K", "paper cycle: hip air at the end of its 1 s charge", "K"),
                           ("bang_bang_switchings_per_s", "bang-bang holding 3 bar for 4 s: switchings per second", ""),
                           ("bang_bang_air_used_L_std", "bang-bang holding 3 bar for 4 s: air used", "L std")):
        for cell, run in ((rows[col][1], a), (rows[col][2], h)):
            check(cell, [("^" + NUM + (" " + unit if unit else "") + "$", run[key])])
