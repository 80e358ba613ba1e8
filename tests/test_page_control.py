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
    assert {"four": 4}[m.group(1)] == len(others)


# --- the board: counts, rates and bounds the page works out -----------------------------------------
def test_the_gain_bounds_are_the_ones_the_loader_allows():
    import frogsim
    from frogsim.errors import ScenarioError
    raw = frogsim.load_robot_scenario("hip-angle-in-air").raw
    text = " ".join(section(DOC, "The gains' bounds:", "Every setting is a variable path of the robot").split())
    allowed = {}
    for key, big in (("proportional_gain", "1e9 bar/rad"), ("derivative_gain", "1e9 bar*s/rad"),
                     ("integral_gain", "1e15 bar/(rad*s)")):
        with pytest.raises(ScenarioError) as exc:
            frogsim.load_robot_scenario(frogsim.with_overrides(raw, {f"controllers.hip.{key}": big}))
        allowed[key] = float(re.search(r"allowed: 0 to ([\d.e+]+) ", str(exc.value)).group(1))
    rng = frogsim.load_robot_scenario("hip-angle-in-air").pneumatic
    check(text, [(r"that is " + NUM + " bar/rad", allowed["proportional_gain"]),
                 (r"bar/rad, " + NUM + " bar·s/rad", allowed["derivative_gain"]),
                 (r"and " + NUM + r"e6 bar/\(rad·s\)", allowed["integral_gain"] / 1e6)])
    hip_range = float(re.search(r"joint's range \((\d+) deg", str(exc.value)).group(1))
    check(text, [(r"\(" + NUM + r" deg\s+at the hip\)", hip_range / 1000)])
    assert rng.controller.rate == 1000.0 and "1 kHz" in text


def test_the_fastest_controller_rate():
    from frogsim.scenario.schema import CONTROLLER_RATE_MAX
    text = " ".join(DOC.split())
    check(text, [(r"`controller.rate` is at most " + NUM + " kHz", CONTROLLER_RATE_MAX / 1e3)])


def test_the_fixed_point_and_fault_counts_of_the_default_lines():
    import frogsim
    from frogsim.control import fixed
    from frogsim.scenario.load import with_firmware
    sc = frogsim.load_robot_scenario(with_firmware("hip-angle-in-air")).pneumatic
    fw = sc.firmware
    text = " ".join(DOC.split())
    lo, hi = fixed.fault_limits(sc)["pressure"]
    check(text, [(r"a 10-bit count below " + NUM, lo), (r"below \d+ or above " + NUM, hi)])
    line = fixed.pressure_volts(fw)
    check(text, [(r"3 bar is round\(16 x " + NUM + r"\)", float(fixed.real_count(line, fw, 3e5))),
                 (r"3 bar is round\(16 x [\d.]+\) = " + NUM, fixed.q4(line, fw, 3e5))])
    # an angle count per sample as a velocity, at the controller's rate
    rad_per_count = 1.0 / (fixed.q4_per_unit(fixed.angle_line(sc)[0], fw) / 16)
    check(text, [(r"one count per sample is " + NUM + r" rad/s at 1 kHz", rad_per_count * sc.controller.rate)])


def test_the_firmware_twin_on_hip_angle_in_air_against_the_float_law():
    import frogsim
    from frogsim.scenario.load import with_firmware
    flt = frogsim.swim("hip-angle-in-air").control_metrics()["hip"]
    fw = frogsim.swim(with_firmware("hip-angle-in-air")).control_metrics()["hip"]
    text = " ".join(section(DOC, "The sliding mode's valve model (Eq. 8) is a table").split())
    check(text, [(NUM + r" deg RMS\s+after 1.5 s", fw["tracking_error_rms_deg"]),
                 (r"after 1.5 s against " + NUM + " deg", flt["tracking_error_rms_deg"]),
                 (r"about " + NUM + " times as often", fw["switchings_per_s"] / flt["switchings_per_s"]),
                 (r"\(" + NUM + " against", fw["switchings_per_s"]),
                 (r"against " + NUM + " switchings per second", flt["switchings_per_s"])])
    assert fw["settle_s"] == 1.5


# --- the gait search's baseline -------------------------------------------------------------------
def test_the_swim_source_pressure_per_cycle_and_the_one_cycle_speed():
    import frogsim
    s10 = frogsim.swim("swim").summary()
    s1 = frogsim.swim("swim", cycles=1).summary()
    p = s10["source_pressure_each_cycle_start_bar_gauge"]
    change = lambda c: 100 * (p[c] - p[c - 1]) / p[c - 1]      # noqa: E731  cycle c, from 1
    text = " ".join(section(DOC, "Every trial runs the evaluated cycles").split())
    check(text, [(r"changes by " + NUM + " % in cycle 1,", change(1)), (NUM + " % in cycle 6", change(6)),
                 (NUM + " % in cycle 10", change(10)), (r"changes by " + NUM + " % over the last of the 1",
                                                        change(1)),
                 (r"speed is " + NUM + " m/s against", s1["mean_speed_m_per_s"]),
                 (r"against " + NUM + " m/s over 10 cycles", s10["mean_speed_m_per_s"])])
    assert s10["cycles"] == 10


# --- the joint-control benchmark's robot ------------------------------------------------------------
def test_the_joint_control_benchmarks_robot_tracks_and_steps_as_the_page_says():
    """The robot of benchmarks/bench_joint_control.py (the full robot swimming, six joint-angle
    controllers on 1 Hz sines), run here as the benchmark builds it: the hip's tracking error the
    page quotes ("In water") and the right-hand sides per MuJoCo step ("Cost"), neither a wall-clock
    figure."""
    import sys

    import frogsim
    from page_numbers import ROOT
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from bench_joint_control import scenario
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    sc = scenario(True)
    assert len(sc.muscles) == 12                          # "the 12-muscle circuit"
    r = frogsim.swim(sc)
    m = r.control_metrics()
    text = " ".join(DOC.split())
    for side in ("left", "right"):
        check(text, [(r"swimming robot, hip RMS error " + NUM + " deg", m[f"hip_{side}"]["tracking_error_rms_deg"])])
    cost = " ".join(section(DOC, "### Cost (benchmarks/bench_joint_control.py)").split())
    check(cost, [(r"the pneumatic driver \(about " + NUM + " right-hand sides of the 12-muscle circuit per step",
                  r.stats["rhs_evaluations"] / r.stats["mujoco_steps"])])


# --- the design-valve-type study ------------------------------------------------------------------
def test_design_valve_type_table_and_text(study):
    runs = study("design-valve-type").summary["design_valve_type"]["runs"]
    rows = table_rows(DOC, "### The `design-valve-type` study")
    assert set(rows) == {"valve / law", *runs}, rows
    for name, r in runs.items():
        cells = rows[name]
        check(cells[1], [(r"^" + NUM + " ms$", 1e3 * r["rise_time_s"])])
        check(cells[2], [(r"^" + NUM + " ms$", 1e3 * r["fall_time_s"])])
        check(cells[3], [(r"^" + NUM + r" mbar", 1e3 * r["sine_rms_bar"]), (r"\(" + NUM + r"\)$", 1e3 * r["sine_max_bar"])])
        check(cells[4], [(r"^" + NUM + " L std$", r["air_per_cycle_L_std"])])
        check(cells[5], [(r"^" + NUM + " L/min$", r["full_open_flow_L_per_min"])])
        check(cells[6], [(r"^" + NUM + " g", 1e3 * r["mass_per_muscle_kg"]), (NUM + " EUR$", r["price_per_muscle_EUR"])])
    pr, sw = runs["proportional / pid"], runs["switching / bang-bang"]
    text = section(DOC, "### The `design-valve-type` study")
    check(text, [(NUM + " times the mass", pr["mass_per_muscle_kg"] / sw["mass_per_muscle_kg"]),
                 (NUM + " times the price", pr["price_per_muscle_EUR"] / sw["price_per_muscle_EUR"])])
    # the valve's conductance the section above quotes: from the catalogue's nominal flow
    from frogsim.circuit.valves.proportional import ProportionalValve
    above = section(DOC, "## The proportional valve and the `pid` kind", "### The `design-valve-type` study")
    C = ProportionalValve().sonic_conductance
    check(above, [(r"C = " + NUM + r" L/\(s bar\) fully open", C * 1e8), (r"\(" + NUM + " times the MHJ9", C / 0.4e-8)])
