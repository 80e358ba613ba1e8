"""The numbers docs/robot.md quotes from runs are the code's: the leg-in-air and swimming tables and
the thrust's dip at the hips' stops are recomputed here from the runs the page names and must read
the same at the precision the page writes them. A change that moves a number fails here; update
the page with it."""
from __future__ import annotations

import numpy as np
import pytest

import frogsim
from page_numbers import NUM, ROOT, check, page, same_to_figures, section, table_rows

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


@pytest.fixture(scope="module")
def leg_in_air():
    return frogsim.swim("leg-in-air")             # what `frogsim reproduce leg-in-air` runs


def test_leg_in_air_table(leg_in_air):
    s = leg_in_air.summary()
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


def test_the_step_and_strip_sensitivity_of_the_swim_distance(swim10):
    text = " ".join(section(DOC, "### The coupled step").split())
    d0 = swim10.summary()["distance_m"]

    def change(**o):
        return 100 * abs(swim_run(**o).summary()["distance_m"] - d0) / d0
    check(text, [(r"Halving the MuJoCo step changes the swim distance by " + NUM + " %",
                  change(**{"robot.timestep": "0.5 ms"})),
                 (r"steps\) by " + NUM + " %", change(**{"robot.timestep": "2 ms", "controller.rate": "500 Hz"}))])
    assert "the controller then at 500 Hz" in text
    limit = float(__import__("re").search(r"instead of 6 by less than ([\d.]+) %", text).group(1))
    assert max(change(**{"hydro.strips": 3}), change(**{"hydro.strips": 24})) < limit


# --- the model's numbers: force law, added masses, masses, pads ----------------------------------------
def _hip_braid():
    from frogsim.physics.muscle import braid_parameters
    mt = frogsim.load_scenario("paper-cycle").muscle_types["hip"]
    return mt, braid_parameters(mt.nominal_length, mt.inner_diameter, mt.braid_angle)


def test_the_muscle_force_numbers():
    import math
    import re

    from frogsim.components.dmsp20 import REFERENCE, law_forces
    from frogsim.physics.muscle_force import chou_hannaford_force
    from frogsim.robot.params import parameter_set_law
    mt, (b0, n) = _hip_braid()
    law = parameter_set_law(frogsim.load_scenario("paper-cycle"))
    consts = (law.force_scale, law.strain_scale, law.stiffness, law.stretch_stiffness, law.stretch_quadratic)
    text = " ".join(section(DOC, "### Muscle force").split())
    check(text, [(NUM + r" N at 6 bar and rest length", chou_hannaford_force(6e5, mt.nominal_length, b0, n)),
                 (r"\(20 mm, " + NUM + r"°\)", math.degrees(mt.braid_angle)),
                 (r"zero at " + NUM + " % contraction", 100 * (1 - b0 / math.sqrt(3) / mt.nominal_length)),
                 (r"the law gives " + NUM + " N at 0 %", float(law_forces([6e5], [0.0], consts)[0])),
                 (r"and " + NUM + r" N\s+at 25 %", float(law_forces([6e5], [0.25], consts)[0]))])
    # the held-out rows (2, 4, 6 bar) over 0-20 %: the largest error and where
    worst = (0.0, None, None)
    for p in (2e5, 4e5, 6e5):
        eps, force = (np.asarray(v, float) for v in REFERENCE[p])
        keep = (eps >= 0) & (eps <= 0.2)
        err = np.abs(law_forces(np.full(keep.sum(), p), eps[keep], consts) - force[keep])
        k = int(np.argmax(err))
        if err[k] > worst[0]:
            worst = (err[k], p, eps[keep][k])
    m = re.search(r"largest error (\d+) N, at (\d+) bar and ([\d.]+) %", text)
    assert same(m.group(1), worst[0]) and float(m.group(2)) == worst[1] / 1e5 and same(m.group(3), 100 * worst[2])


def same(text, value):
    from page_numbers import same_as_written
    return same_as_written(text, value)


def test_the_added_masses_and_the_mass_budget():
    from frogsim.engine.coupled import build_coupled
    from frogsim.physics.hydro import fan_added_mass
    from frogsim.robot.water import E_FAN, E_IA, E_LIMB, E_MA, P_PHI_FOLD, P_PHI_OPEN
    rs = frogsim.load_robot_scenario("swim")
    a = build_coupled(rs).arrays
    el, pa = a["el"], a["pa"]
    hull = next(e for e in range(el.shape[0]) if el[e, E_LIMB] < 0.5)
    segment = next(e for e in range(el.shape[0]) if el[e, E_LIMB] > 0.5 and el[e, E_FAN] < 0)
    palm = next(e for e in range(el.shape[0]) if el[e, E_FAN] >= 0)
    p = int(el[palm, E_FAN])
    open_, folded = (fan_added_mass(*el[palm, E_MA:E_MA + 3], *el[palm, E_IA:E_IA + 3], pa[p, phi])[1]
                     for phi in (P_PHI_OPEN, P_PHI_FOLD))
    text = " ".join(section(DOC, "### Water").split())
    surge, sway, heave = el[hull, E_MA:E_MA + 3]
    check(text, [(r"surge " + NUM + " kg", surge), (r"sway " + NUM + " kg", sway), (r"heave " + NUM + " kg", heave),
                 (r"per length across its axis \(" + NUM + r" kg\)", el[segment, E_MA + 1]),
                 (NUM + " kg open", open_), (NUM + " kg folded", folded)])
    rows = table_rows(DOC, "| part | mass | how |")
    hull_row = next(v for k, v in rows.items() if k.startswith("hull"))
    check(hull_row[1], [("^" + NUM + " kg \\+", rs.layout.trunk_mass), (r"\+ " + NUM + " kg ballast", rs.layout.ballast)])


def test_the_pads_stiffness_is_the_pads_the_page_derives():
    import math
    import re
    text = " ".join(section(DOC, "### Legs, cranks and joints").split())
    m = re.search(r"(\d+) mm across and (\d+) mm thick \(Young's modulus ([\d.]+) MPa", text)
    d, t, E = float(m.group(1)) * 1e-3, float(m.group(2)) * 1e-3, float(m.group(3)) * 1e6
    k_pad = E * math.pi * d ** 2 / 4 / t
    check(text, [(r"Gent 1958; " + NUM + "e6 N/m", k_pad / 1e6)])
    raw = frogsim.load_robot_scenario("swim")
    from frogsim.engine import coupled as C
    stops = C.build_coupled(raw).arrays["stops"]
    for joint, arm, pattern in ((0, "100", r"\(" + NUM + r" N m/rad\)"), (1, "70", r"knee's \(" + NUM + r"\)"),
                                (2, "60", r"ankle's \(" + NUM + r"\)")):
        found = re.findall(pattern, text)
        assert len(found) == 1 and same_to_figures(found[0], k_pad * (float(arm) * 1e-3) ** 2), (found, arm)
        check(text, [(pattern, stops[joint, C.STOP_K])])
    check(text, [(r"0\.15: " + NUM + ",", stops[0, C.STOP_C]), (r", " + NUM + r" and [\d.]+ N m s", stops[1, C.STOP_C]),
                 (r"and " + NUM + " N m s with", stops[2, C.STOP_C])])


def test_the_full_robot_stalls_as_the_page_says(swim10):
    """The prose under the swim table: the full robot uses a third more air than the spring-recovery
    robot, stalls after four cycles (each later cycle under a fifth of the first's distance, the
    first four above it), and its exhaust and source pressures are the page's bars apart after
    four cycles and from the sixth cycle on (at each cycle's end)."""
    import re
    text = " ".join(section(DOC, "The robot accelerates only while its legs extend").split())
    full = swim_run(**{"robot.recovery": "muscle"})
    s, s6 = full.summary(), swim10.summary()
    assert "uses a third more air" in text
    assert abs(s["air_used_per_cycle_L_std"] / s6["air_used_per_cycle_L_std"] - 4.0 / 3.0) < 0.05
    d = s["distance_each_cycle_m"]
    assert "stalls after four cycles" in text and "less than a fifth of the first's distance" in text
    assert all(x > d[0] / 5 for x in d[:4]) and all(x < d[0] / 5 for x in d[4:]), d
    m = re.search(r"(\d+\.\d) bar apart after four cycles and (\d+\.\d) bar from the sixth on", text)
    assert m, text
    df = full.to_dataframe()
    gap = (df["source_pressure_Pa_abs"].to_numpy() - df["exhaust_pressure_Pa_abs"].to_numpy()) / 1e5
    t = np.asarray(full.t)
    at_end = [float(gap[np.searchsorted(t, 2.0 * c) - 1]) for c in range(1, 11)]
    assert f"{at_end[3]:.1f}" == m.group(1), at_end
    assert all(f"{g:.1f}" == m.group(2) for g in at_end[5:]), at_end


def test_what_the_vented_muscles_still_pull_in_air(leg_in_air):
    """The prose under the leg-in-air figure: the driving muscles' tensions and the joints' angles
    (hip, knee, ankle of the left leg) on average over the run's last 0.3 s, at the page's
    precision."""
    import re
    text = " ".join(section(DOC, "The hip pressure with the volume from").split())
    m = re.search(r"keep pulling \((\d+), (\d+) and (\d+) N at hip, knee and ankle on average over the run's last "
                  r"(\d+\.\d) s\) and hold the legs a few degrees open against the springs \((\d+\.\d), (\d+\.\d) and "
                  r"(\d+\.\d) deg on average then\)", text)
    assert m, text
    r = leg_in_air
    t = np.asarray(r.t)
    late = t >= t[-1] - float(m.group(4)) - 1e-9
    df = r.to_dataframe()
    legs = ("hip_left", "knee_left", "ankle_left")
    pull = [f"{df[j + '_tension_N'].to_numpy()[late].mean():.0f}" for j in legs]
    cols = [list(r.model.joint_names).index(j) for j in legs]
    ang = [f"{np.degrees(r.joint_angles[late][:, c]).mean():.1f}" for c in cols]
    assert pull == list(m.group(1, 2, 3)) and ang == list(m.group(5, 6, 7)), (pull, ang)


def test_the_readmes_swim_figures_are_this_run(swim10):
    """README.md, "The robot swimming": `frogsim swim swim --cycles 10` with the paper's timing and
    spring recovery, the run the swimming table's first column is."""
    s = swim10.summary()
    readme = (ROOT / "README.md").read_text()
    text = " ".join(readme[readme.index("With the paper's timing and spring recovery:"):].split())
    check(text, [(r"recovery: " + NUM + " m/s", s["mean_speed_m_per_s"]),
                 (r"m/s \(" + NUM + " body lengths/s", s["mean_speed_body_lengths_per_s"]),
                 (r"body lengths/s\), " + NUM + " m and", s["distance_per_cycle_m"]),
                 (r"m and " + NUM + " L of air per cycle", s["air_used_per_cycle_L_std"]),
                 (r"falling from " + NUM + " to", s["source_pressure_each_cycle_start_bar_gauge"][0]),
                 (r"from \d+ to " + NUM + " bar in", s["source_pressure_after_cycles_bar_gauge"]),
                 (r"bar in " + NUM + " cycles", s["cycles"])])
