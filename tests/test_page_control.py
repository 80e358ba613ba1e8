"""The numbers docs/control.md quotes from its studies are the code's: each is recomputed from the
study (or the run) the page names and must read the same at the precision the page writes it. A
change that moves a number fails here; update the page with it."""
from __future__ import annotations

import re

import pytest

from page_numbers import NUM, check, page, section, table_rows

DOC = page("control.md")


# --- the control-joint study ----------------------------------------------------------------------
def test_control_joint_table_and_text(study):
    s = study("control-joint").summary["control_joint"]
    rows = table_rows(DOC, "### The `control-joint` study")
    assert set(rows) == {"p0", "1.5 bar", "3.5 bar"}, rows
    for level in ("1.5", "3.5"):
        cells, run = rows[f"{level} bar"], s["runs"][f"{level}_bar"]
        step, sine = run["step"], run["sine"]
        check(cells[1], [(r"^" + NUM + r" / ", step["tracking_error_rms_deg"]),
                         (r" / " + NUM + r" deg$", step["tracking_error_max_deg"])])
        check(cells[2], [(r"^" + NUM + " ms$", 1e3 * step["rise_time_s"])])
        check(cells[3], [(r"^" + NUM + r" / ", sine["tracking_error_rms_deg"]),
                         (r" / " + NUM + r" deg$", sine["tracking_error_max_deg"])])
        check(cells[4], [(r"^" + NUM + r"$", sine["switchings_per_s"])])
        check(cells[5], [(r"^" + NUM + r" L std$", sine["air_used_L_std"])])
    # the paragraph under the table
    from frogsim.studies.control_joint import scenario
    lo, hi = s["runs"]["1.5_bar"]["sine"], s["runs"]["3.5_bar"]["sine"]
    sc = scenario("sine", 1.5).pneumatic
    samples = round(sc.duration * sc.controller.rate)
    text = " ".join(section(DOC, "### The `control-joint` study").split())
    check(text, [(r"uses " + NUM + r" times the air", hi["air_used_L_std"] / lo["air_used_L_std"]),
                 (r"at " + NUM + r" of the sine's", lo["samples_pressure_target_clipped"]),
                 (r"of the sine's " + NUM + " samples", samples),
                 (r"samples \(" + NUM + r" %\)", 100 * lo["samples_pressure_target_clipped"] / samples)])
    # "tracks worse" with the stiffer joint: the page's word against the run
    assert "tracks *worse*" in text and hi["tracking_error_rms_deg"] > lo["tracking_error_rms_deg"]


# --- the control-pressure study -------------------------------------------------------------------
def test_control_pressure_table_and_sweep(study):
    s = study("control-pressure").summary["control_pressure"]
    rows = table_rows(DOC, "## The `control-pressure` study")
    assert set(rows) == {"law", "pwm", "bang-bang", "sliding mode"}, rows
    for label, key in (("pwm", "pwm"), ("bang-bang", "bang-bang"), ("sliding mode", "sliding-mode")):
        cells, run = rows[label], s["runs"]["sine"][key]
        check(cells[1], [(r"^" + NUM + " mbar$", 1e3 * run["tracking_error_rms_bar"])])
        check(cells[2], [(r"^" + NUM + " mbar$", 1e3 * run["tracking_error_max_bar"])])
        check(cells[3], [(r"^" + NUM + "$", run["switchings_per_s"])])
        check(cells[4], [(r"^" + NUM + " L std$", run["air_used_L_std"])])
    text = " ".join(section(DOC, "## The `control-pressure` study").split())
    bb, sm = s["runs"]["sine"]["bang-bang"], s["runs"]["sine"]["sliding-mode"]
    # "switches about 50 % more": the written share, to the nearest 10 %
    more = 100 * (sm["switchings_per_s"] / bb["switchings_per_s"] - 1)
    check(text, [(r"switches about " + NUM + " % more", round(more, -1))])
    assert s["sliding_mode_fewer_switchings_no_worse_rms"] is False and "does **not** track" in text

    def point(law, key, value):
        return next(p for p in s["sine_tradeoff"][law] if p[key] == pytest.approx(value))
    b_lo, b_hi = point("bang-bang", "band_bar", 0.05), point("bang-bang", "band_bar", 0.3)
    m_lo, m_hi = point("sliding-mode", "penalty_bar", 0.05), point("sliding-mode", "penalty_bar", 0.1)
    check(text, [
        (r"\(0\.05 bar: " + NUM + " mbar at", 1e3 * b_lo["tracking_error_rms_bar"]),
        (r"mbar at " + NUM + r" switchings/s, against", b_lo["switchings_per_s"]),
        (r"against " + NUM + r" mbar at [\d.]+ switchings/s with", 1e3 * m_lo["tracking_error_rms_bar"]),
        (r"mbar at " + NUM + r" switchings/s with\s+ρ = 0\.05", m_lo["switchings_per_s"]),
        (r"\(0\.3 bar: " + NUM + " mbar", 1e3 * b_hi["tracking_error_rms_bar"]),
        (r"mbar at " + NUM + r"/s, against", b_hi["switchings_per_s"]),
        (r"against " + NUM + r" mbar at [\d.]+/s with", 1e3 * m_hi["tracking_error_rms_bar"]),
        (r"mbar at " + NUM + r"/s with\s+ρ = 0\.1 bar", m_hi["switchings_per_s"]),
    ])
    # the two settings the page names are the ones the sweep finds beaten
    assert s["bang_bang_settings_beaten_by_sliding_mode"] == 2 and "not in between" in text


# --- the pages' words about the control command ---------------------------------------------------
def test_the_control_command_runs_the_studies_the_page_names():
    from frogsim.studies import studies_in
    text = " ".join(section(DOC, "## The `control-pressure` study").split())
    m = re.search(r"runs it with the other (\w+) control studies, ([^)]*)\)", text)
    assert m, text[:400]
    others = re.findall(r"`([\w-]+)`", m.group(2))
    assert ["control-pressure"] + others == studies_in("control")
    assert {"three": 3}[m.group(1)] == len(others)
