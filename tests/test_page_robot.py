"""The numbers docs/robot.md quotes from runs are the code's: the leg-in-air and swimming tables and
the thrust's dip at the hips' stops are recomputed here from the runs the page names and must read
the same at the precision the page writes them. A change that moves a number fails here; update
the page with it."""
from __future__ import annotations

import numpy as np
import pytest

import frogsim
from page_numbers import NUM, check, page, section, table_rows

DOC = page("robot.md")
SIGNED = r"([+−-]?\d+(?:\.\d+)?)"


def swim_run(output_interval=None, **overrides):
    raw = frogsim.load_robot_scenario("swim").raw
    if output_interval:
        overrides["output_interval"] = output_interval
    return frogsim.swim(frogsim.load_robot_scenario(frogsim.with_overrides(raw, overrides)))


@pytest.fixture(scope="module")
def swim10():
    return swim_run()            # `frogsim swim swim --cycles 10`: the scenario's 10 cycles, 10 ms output


def test_leg_in_air_table():
    s = frogsim.swim("leg-in-air").summary()      # what `frogsim reproduce leg-in-air` runs
    rows = table_rows(DOC, "Leg in air (`frogsim reproduce leg-in-air")
    legs = ("hip_left", "knee_left", "ankle_left")
    delay = rows["joint delay hip / knee / ankle"][1]
    rng = rows["joint range hip / knee / ankle"][1]
    aer = rows["hip / knee / ankle aeration volume"][1]
    for k, j in enumerate(legs):
        pick = r" / ".join([NUM if i == k else r"[\d.]+" for i in range(3)])
        check(delay, [(pick + " s", s["joint_delay_s"][j])])
        check(rng, [(pick + "°", s["joints"][j]["max_deg"] - s["joints"][j]["min_deg"])])
        check(aer, [(pick + " L", s["aeration_volume_L_std"][j])])
    check(rows["hip muscle largest contraction"][1], [("^" + NUM + " %$", s["max_contraction_percent"]["hip_left"])])
    # the exhaust the released muscles vent to, "by then" (the run's end)
    text = " ".join(section(DOC, "The hip pressure with the volume from").split())
    check(text, [(r"exhaust chamber \(" + NUM + " bar gauge by then", s["exhaust_pressure_after_cycles_bar_gauge"])])


def _check_swim_column(rows, col, s):
    cell = lambda label: rows[label][col]       # noqa: E731
    check(cell("mean speed"), [("^" + NUM + " m/s", s["mean_speed_m_per_s"]),
                               ("= " + NUM + " body", s["mean_speed_body_lengths_per_s"])])
    each = s["distance_each_cycle_m"]
    check(cell("distance per cycle (first, last)"), [("^" + NUM + r" m \(", s["distance_per_cycle_m"]),
                                                    (r"\(" + NUM + ",", each[0]), (", " + NUM + r"\)", each[-1])])
    check(cell("thrust peak (whole run / in extension)"), [("^" + NUM + " ", s["thrust_peak_N"]),
                                                          (" / " + NUM + " N$", s["thrust_peak_extension_N"])])
    check(cell("thrust mean (whole run / in extension / in recovery)"), [
        ("^" + SIGNED + " / ", s["thrust_mean_N"]), (" / " + SIGNED + " / ", s["thrust_mean_extension_N"]),
        (" / " + SIGNED + " N$", s["thrust_mean_recovery_N"])])
    check(cell("forward acceleration, extension / recovery"), [
        ("^" + SIGNED + " / ", s["forward_acceleration_mean_extension_m_per_s2"]),
        (" / " + SIGNED + " m/s²$", s["forward_acceleration_mean_recovery_m_per_s2"])])
    check(cell("air per cycle"), [("^" + NUM + " L", s["air_used_per_cycle_L_std"])])
    check(cell("source after 10 cycles"), [("^" + NUM + " bar gauge", s["source_pressure_after_cycles_bar_gauge"]),
                                          (r"\(exhaust " + NUM + r"\)", s["exhaust_pressure_after_cycles_bar_gauge"])])
    check(cell("cost of transport"), [("^" + NUM + "$", s["cost_of_transport"])])
    assert s["cycles"] == 10


def test_swim_table_spring_recovery(swim10):
    rows = table_rows(DOC, "Swimming (`frogsim swim swim --cycles 10")
    _check_swim_column(rows, 1, swim10.summary())


def test_swim_table_full_robot():
    # bench_swim.py's case: the shipped swim with robot.recovery = "muscle"
    rows = table_rows(DOC, "Swimming (`frogsim swim swim --cycles 10")
    s = swim_run(**{"robot.recovery": "muscle"}).summary()
    assert len(s["max_contraction_percent"]) == 12
    _check_swim_column(rows, 2, s)


def test_the_air_is_conserved_to_the_drift_the_page_gives(swim10):
    text = " ".join(section(DOC, "### The coupled step").split())
    m = __import__("re").search(r"`air_mass_relative_drift` ≈ (\d)e-(\d+)", text)
    drift = swim10.summary()["air_mass_relative_drift"]
    assert f"{drift:.0e}" == f"{m.group(1)}e-{m.group(2)}", (drift, m.group(0))


def _dips(run):
    """Per gait cycle: the thrust's least value [N], and how long [ms] it stays below half of that
    around it, and whether a hip was at or past its extended stop pad when the dip began."""
    from frogsim.engine import coupled as C
    t, th = run.t, run.thrust
    upper = run.model.arrays["stops"][0, C.STOP_UPPER]
    hips = run.joint_angles[:, [0, 3]] if run.joint_angles.shape[1] == 6 else run.joint_angles[:, :1]
    h = float(np.diff(t)[0])
    out = []
    for c in range(int(round(t[-1] / 2.0))):
        idx = np.nonzero((t >= 2 * c) & (t < 2 * c + 2))[0]
        i = idx[np.argmin(th[idx])]
        lo = i
        while th[lo - 1] < th[i] / 2:
            lo -= 1
        hi = i
        while th[hi + 1] < th[i] / 2:
            hi += 1
        at_stop = bool((hips[max(lo - 3, 0):lo + 1] >= upper).any())
        out.append((th[i], (hi - lo + 1) * h * 1e3, at_stop))
    return out


def test_the_thrust_dip_at_the_stops_every_step_recorded_and_at_the_default_output(swim10):
    text = " ".join(section(DOC, "- Quasi-steady water", "- Stop pads").split())
    fine = _dips(swim_run("1 ms"))
    coarse = _dips(swim10)
    assert len(fine) == len(coarse) == 10
    assert all(at for _, _, at in fine), fine                   # each dip begins at a hip's extended pad
    widths = [w for _, w, _ in fine]
    check(text, [("for " + NUM + "-", min(widths)), (r"-" + NUM + " ms", max(widths)),
                 (r"to " + SIGNED + " N in the first", fine[0][0]),
                 (r"and " + SIGNED + " N in the last", fine[-1][0]),
                 (r"dip: " + SIGNED + " and", coarse[0][0]), (r" and " + SIGNED + r" N\)", coarse[-1][0])])
    # the deepest and shallowest are the first and the last: the page's "in the first ... in the last"
    assert min(d for d, _, _ in fine) == fine[0][0] and max(d for d, _, _ in fine) == fine[-1][0]
    assert "--output-interval 1 ms" in text
