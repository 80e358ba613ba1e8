"""A published air-vessel measurement reproduced by a fitted wall heat transfer coefficient h.

The data: measured air traces of a 16.2 L steel vessel (0.515 m x 0.20 m) shipped in HydDown
(github.com/andr1976/HydDown, commit 1040d758b819533451086baa5cf2a47b4292a22f, files
validation/Air_790kPa_21mm.yml and validation/Air_3-7kPa_271mm.yml), probably from Thorncroft,
Patton & Gordon (2007), ASEE AC 2007-2695, doi:10.18260/1-2--2911 (HydDown does not say so). The
points below are copied verbatim from those files; examples/fit/tank-heat holds them as traces.

Once the flow through the orifice has stopped, the vessel stays open to the atmosphere: its air
relaxes to the wall temperature T_a at constant pressure p. For an ideal gas in a rigid volume V
the internal energy p V c_v/R is then constant, so the heat Q = h A (T_a - T) is carried off by the
air leaving (discharge, at T) or drawn in (filling, at T_a) as it expands or shrinks:

    discharge:  m c_p dT/dt = h A (T_a - T)              tau = m c_p/(h A)
    filling:    m c_p (T_a/T) dT/dt = h A (T_a - T)      tau = m c_p T_a/(T h A)

with m = p V/(R T): T_a - T ~ exp(-t/tau), so a straight-line fit of ln|T_a - T| against t gives
tau and h, with the regression's own interval. That h comes from the measured points and these
closed forms only (numpy/scipy, no frogsim engine); frogsim's fit of the same points
(FIT-*-recovery.toml: the engine, the orifice, the residual flow) must agree with it.

docs/fitting.md's "After the flow" table and prose are these fits and closed forms, at the
precision the page writes them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import stats

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "fit" / "tank-heat"
R, K = 287.0, 1.4                       # air (the example's parameter set, fan2017)
CP = K * R / (K - 1.0)
V, A = 0.01618, 0.3864                  # m^3, m^2: pi/4 0.2^2 0.515 and its flat-ended wall
P_ATM = 100.6e3                         # Pa: where both runs' measured pressure settles

# (time [s], temperature [K]) verbatim from the files, from the first point at which the flow has
# (almost) stopped: discharge p = 1.0098 bar abs at 42.5 s (1.0074 at 43.2 s), filling 1.0030 bar at
# 21.8 s (the atmosphere 1.006)
DISCHARGE = ([42.5, 46.2, 50.1, 54], [268.6, 272.6, 276, 278.9], 298.0, False)
FILLING = ([21.8, 27.3, 29.1, 31.6, 35.4, 46.3, 55.2, 64.2, 77.8],
           [311.4, 310, 308.2, 304.8, 306, 303.3, 301.5, 300.2, 298.8], 295.0, True)
#: how far the closed form's constant m (and T_a/T) may stand from the model's: over the windows T
#: moves 268.6..278.9 K and 311.4..298.8 K, so m = p V/(R T) (and T_a/T) stray up to about 2 % each
#: from their value at the window's mean temperature
MODEL_ALLOWANCE = 0.05


def closed_form_h(times, temps, T_a, filling, confidence=0.95):
    """(h, half-width of its interval) from the log-linear fit of ln|T_a - T| against t [W/(m^2 K)]."""
    t, T = np.asarray(times, float), np.asarray(temps, float)
    r = stats.linregress(t, np.log(np.abs(T_a - T)))
    T_mean = T.mean()
    m = P_ATM * V / (R * T_mean)
    scale = m * CP * (T_a / T_mean if filling else 1.0) / A          # h = scale / tau = -scale * slope
    q = stats.t.ppf(0.5 + confidence / 2, t.size - 2)
    return -scale * r.slope, scale * q * r.stderr


DATA = {"discharge": DISCHARGE, "filling": FILLING}


@pytest.fixture(scope="module")
def recovery():
    """recovery(name) -> (fit spec, its experiment, fit result), each fit run once for this file."""
    from frogsim.fit import fit, load_fit_spec
    done = {}

    def get(name):
        if name not in done:
            spec = load_fit_spec(EXAMPLE / f"FIT-{name}-recovery.toml", starts=1)
            done[name] = (spec, spec.experiments[0], fit(spec))
        return done[name]
    return get


@pytest.mark.parametrize("name", ["discharge", "filling"])
def test_fitted_h_agrees_with_the_recovery_time_constant(name, recovery):
    times, temps, T_a, filling = DATA[name]
    h_cf, half = closed_form_h(times, temps, T_a, filling)
    assert 0.5 < h_cf < 5.0               # free convection of air at 1 bar: a few W/(m^2 K)
    spec, e, res = recovery(name)
    # the spec starts where the data say: the first point, the ambient, no other fitted setting
    assert e.scenario.source.initial_temperature == pytest.approx(temps[0])
    assert e.scenario.air.ambient_temperature == pytest.approx(T_a)
    np.testing.assert_allclose(e.trace.time + times[0], times, atol=1e-9)
    h, lo, hi = res.values[0], res.ci_low[0], res.ci_high[0]
    print(f"{name}: frogsim h = {h:.3f} W/(m^2 K) ({lo:.3f} .. {hi:.3f}); closed form "
          f"{h_cf:.3f} +- {half:.3f}")
    assert abs(h - h_cf) <= half + MODEL_ALLOWANCE * h_cf     # within the data's scatter and the model allowance
    assert lo < h_cf < hi                                     # and the closed form inside frogsim's interval
    assert lo > 0.0                                           # the data do see the wall's heat
    swing = max(temps) - min(temps)
    assert res.rms_residual[(e.name, "source temperature")] < 0.15 * swing


def _tau(times, temps, T_a):
    """The recovery's time constant [s]: the closed form's straight line through ln|T_a - T|."""
    return -1.0 / stats.linregress(np.asarray(times, float), np.log(np.abs(T_a - np.asarray(temps, float)))).slope


def test_the_pages_recovery_table_and_prose(recovery):
    """docs/fitting.md, "After the flow": each row (window, points, frogsim's h and interval, its rms
    temperature residual, the measured swing, the closed form's h) and the prose under it (how far
    the two h differ, the h it rounds them to, the discharge's tau with the ambient 2 K off)."""
    from page_numbers import NUM, check, page, section, table_rows
    doc = page("fitting.md")
    rows = table_rows(doc, "| recovery | points |")
    assert len(rows) == 2, rows                            # the two runs
    text = " ".join(section(doc, "**After the flow**", "What this means for the robot's").split())
    rel = {}
    for name in ("discharge", "filling"):
        times, temps, T_a, filling = DATA[name]
        _, e, res = recovery(name)
        h, lo, hi = res.values[0], res.ci_low[0], res.ci_high[0]
        h_cf, half = closed_form_h(times, temps, T_a, filling)
        cells = next(v for k, v in rows.items() if k.startswith(name + ","))
        check(cells[0], [(name + ", " + NUM + "-", times[0]), ("-" + NUM + " s,", times[-1]),
                         ("T_a = " + NUM + " K$", T_a)])
        check(cells[1], [("^" + NUM + "$", len(times))])
        check(cells[2], [("^" + NUM + " ", h), (r"\(" + NUM + " ", lo), (r"\.\. " + NUM + r"\)", hi)])
        check(cells[3], [("^" + NUM + " K$", res.rms_residual[(e.name, "source temperature")])])
        check(cells[4], [("^" + NUM + " K$", max(temps) - min(temps))])
        check(cells[5], [("^" + NUM + " ±", h_cf), ("± " + NUM + "$", half)])
        rel[name] = 100 * abs(h - h_cf) / h_cf
        check(text, [(r"h ≈ " + NUM + r" W/\(m² K\) after the " + name, h)] if name == "discharge" else
              [(r"and " + NUM + r" W/\(m² K\) after the filling", h)])
    check(text, [(r"differ by " + NUM + " % and", rel["discharge"]), (r"% and " + NUM + r" %\. The discharge", rel["filling"])])
    times, temps, T_a, _ = DISCHARGE
    tau = {d: _tau(times, temps, T_a + d) for d in (-2.0, 0.0, 2.0)}
    check(text, [(r"τ by −" + NUM + " % /", 100 * (tau[0.0] - tau[-2.0]) / tau[0.0]),
                 (r"% / \+" + NUM + r" % \(", 100 * (tau[2.0] - tau[0.0]) / tau[0.0]),
                 (r"\(" + NUM + " s, [\\d.]+ s against", tau[-2.0]), (r" s, " + NUM + " s against", tau[2.0]),
                 (r"against " + NUM + r" s\)", tau[0.0])])
    # the robot's source tanks against these data: still air 1-2 W/(m^2 K), the recoveries' h
    tail = " ".join(section(doc, "What this means for the robot's parameter set").split())
    lo_h, hi_h = sorted(recovery(n)[2].values[0] for n in ("discharge", "filling"))
    check(tail, [(r"still air \(" + NUM + "-", lo_h), (r"still air \(\d+-" + NUM + r" W", hi_h)])
