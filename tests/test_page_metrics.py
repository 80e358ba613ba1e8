"""docs/metrics.md's examples and numbers are the code's: the "not reached" reason, Fig. 17's
levelled-off curve and Fig. 15's two rise times it explains are recomputed from the paper's studies,
the note it quotes is the one the paper cycle makes, and the reference density from ISO 8778's state."""
from __future__ import annotations

import json
import re

import pytest

import frogsim
from page_numbers import NUM, check, page, section

DOC = page("metrics.md")


def test_the_not_reached_example_is_fig17_at_15_L_per_min(study):
    sweep = study("fig17").summary["saturation_sweep"]
    e = next(x for x in sweep if x["branch_limit_L_per_min"] == 15)
    shown = json.loads("{" + re.search(r"```json\n(.*?)```", DOC, re.S).group(1) + "}")
    assert shown == {"rise_time_90_s": e["rise_time_90_s"], "rise_time_90_reason": e["rise_time_90_reason"]}
    text = " ".join(DOC.split())
    check(text, [(r"15 L/min: " + NUM + " bar of a", e["final_muscle_pressure_bar_gauge"]),
                 (r"bar of a " + NUM + " bar rise", e["rise_target_pressure_bar_gauge"])])


def test_the_fig15_rise_times_the_page_explains(study):
    sat = {x["source_pressure_bar_gauge"]: x for x in study("fig15").summary["source_pressure_sweep"]["saturated"]}
    text = " ".join(section(DOC, "Worth knowing when reading Fig. 15(a)").split())
    check(text, [(r"3 bar source the muscle settles at " + NUM + " bar", sat[3]["final_muscle_pressure_bar_gauge"]),
                 (r"90 % level \(" + NUM + r" s\)", sat[3]["rise_time_90_s"]),
                 (r"after the contraction \(" + NUM + r" s\)", sat[4]["rise_time_90_s"])])


@pytest.fixture(scope="module")
def paper_cycle():
    return frogsim.simulate(frogsim.load_scenario("paper-cycle"))


def test_the_note_is_the_paper_cycles(paper_cycle):
    from frogsim.io.results import limit_notes
    notes = limit_notes(paper_cycle)
    shown = re.search(r"```text\n(note: .*?)\n```", DOC, re.S).group(1)
    assert ["note: " + n for n in notes] == [shown]


def test_the_reference_density(paper_cycle):
    rho = paper_cycle.reference_density
    text = " ".join(DOC.split())
    check(text, [(r"ρ_ref = " + NUM + " kg/m³", rho)])


def test_the_air_mass_drift_is_of_the_order_the_page_gives(paper_cycle):
    """The page: air_mass_relative_drift "~1e-15" (a conservation check: the circuit's air mass
    changes only by rounding). The paper cycle's is within a decade of that order."""
    from frogsim.io.results import run_summary
    row = next(line for line in DOC.splitlines() if line.startswith("| `air_mass_relative_drift`"))
    order = float(re.search(r"~(\d(?:\.\d+)?e-\d+)", row).group(1))
    drift = run_summary(paper_cycle)["air_mass_relative_drift"]
    assert order / 10 <= abs(drift) < order * 10, drift
