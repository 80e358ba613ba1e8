"""The muscles' force hysteresis against a published loop: Hunt, Szczecinski and Quinn 2017's model of
FESTO's 10 mm fluidic muscle (frogsim.components.hunt2017), fitted with the force-table fit.

* the transcription of the published model: the muscle at rest at 0 kPa and fully contracted at
  620 kPa with no load (the lengths the source states), the inversion P -> F exact, and at rest
  length the loop's height in tension the closed form c6 / c5 at every pressure;
* the fit (examples/fit/hysteresis/FIT.toml) finds a loop (slip force > 0 with 95 % confidence)
  whose mean height over the table matches the published mean height, and shows the two
  differences docs/fitting.md explains: Maxwell-slip loops close at the turning points where the
  published one keeps its full height, and the fitted loop grows with pressure where the
  published one shrinks;
* fan2017-hysteresis's slip force is the fitted one scaled by the DMSP-20's to the DMSP-10's
  datasheet force, as its source says.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from frogsim.components import hunt2017 as h

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "fit" / "hysteresis"
BAR = 1e5


def test_the_published_model_holds_the_stated_lengths():
    # 18.9 cm at 0 kPa, 15.75 cm at 620 kPa, both with no load (the source's muscle)
    assert abs(h.pressure(0.0, 0.0, "loading")) < 6e3           # within 6 kPa of 0 (1 % of the range)
    assert h.pressure(h.EPS_MAX, 0.0, "loading") == pytest.approx(620e3, rel=0.01)
    # the shortening branch needs the loop's width more pressure for the same tension
    assert h.pressure(0.05, 100.0, "unloading") - h.pressure(0.05, 100.0, "loading") == pytest.approx(15.6e3)


@settings(max_examples=60, deadline=None)
@given(p=st.floats(50e3, 620e3), eps=st.floats(0.0, 0.16), branch=st.sampled_from(["loading", "unloading"]))
def test_tension_inverts_the_published_pressure(p, eps, branch):
    f = h.tension(p, eps, branch)
    if np.isfinite(f):
        assert f >= 0.0
        assert h.pressure(eps, f, branch) == pytest.approx(p, rel=1e-9, abs=1e-3)
    else:
        # no tension in the model's domain balances p: with no load the muscle needs more pressure
        # than p to sit here, or p lies beyond the pressure at the domain's top tension
        top = h.tension_top(eps)
        # the domain's top: (H)'s denominator still positive, its tangent's argument below pi/2
        assert h.C4 * top + h.EPS_MAX > 0.0
        assert h.C2 * (eps / (h.C4 * top + h.EPS_MAX) + h.C3) < math.pi / 2.0
        assert h.pressure(eps, 0.0, branch) > p or h.pressure(eps, top, branch) < p


@pytest.mark.parametrize("p", [1e5, 3e5, 6e5])
def test_at_rest_length_the_published_loop_is_c6_over_c5_high(p):
    # at eps = 0 the tangent's argument does not depend on F, so (H) is linear in F there
    assert h.loop_width(p, 0.0) == pytest.approx(h.C6 / h.C5, rel=1e-9)


def test_the_shipped_example_is_what_the_module_writes(tmp_path):
    h.write_example(tmp_path)
    for name in (h.TABLE_NAME, h.RIG_NAME, "FIT.toml"):
        assert (EXAMPLE / name).read_text() == (tmp_path / name).read_text(), name


@pytest.fixture(scope="module")
def fitted():
    from frogsim.fit import fit
    return fit(EXAMPLE / "FIT.toml")


def _loop_heights(res):
    """Per table row present on both branches: (pressure, contraction, published height, fitted
    height) [Pa, -, N, N], heights loading less unloading (the study's row-by-row comparison)."""
    from frogsim.studies.hysteresis import loop_heights
    return np.array([(r["pressure_bar_gauge"] * BAR, e, a, b) for r in loop_heights(res)
                     for e, a, b in zip(r["contraction"], r["published_height_N"], r["fitted_height_N"])])


def test_the_fit_finds_the_published_loop_on_average(fitted):
    j = [prm.path for prm in fitted.spec.parameters].index("muscle_force.slip_per_pressure")
    assert fitted.ci_low[j] > 0.0, "the published loop must be resolved"
    rows = _loop_heights(fitted)
    published, model = rows[:, 2].mean(), rows[:, 3].mean()
    assert model == pytest.approx(published, rel=0.15), (published, model)
    # the forces themselves: within 5 % of the table's largest force, rms over every row
    err = fitted.force_curves[0]["after"] - fitted.spec.force_tables[0].table.force
    assert np.sqrt(np.mean(err ** 2)) < 0.05 * fitted.spec.force_tables[0].table.force.max()


def test_the_differences_the_docs_explain(fitted):
    rows = _loop_heights(fitted)
    rest = rows[rows[:, 1] == 0.0]
    # a Maxwell-slip loop closes at its turning point (rest length is each pressure's smallest
    # contraction in the table); the published one keeps its full height c6 / c5 there
    assert np.all(np.abs(rest[:, 3]) < 1e-9)
    assert np.all(np.abs(rest[:, 2] - h.C6 / h.C5) < 1e-6)
    # the published loop (a constant pressure offset) is lower at 6 bar than at 3 bar at the same
    # contraction; the fitted one (slip force proportional to pressure) is higher
    at4 = {p: r for p, _, *r in rows[np.isclose(rows[:, 1], 0.04)]}
    assert at4[6 * BAR][0] < at4[3 * BAR][0]
    assert at4[6 * BAR][1] > at4[3 * BAR][1]


def test_fan2017_hysteresis_is_the_fit_scaled_to_the_dmsp20(fitted):
    from frogsim.robot.params import MuscleForceLaw
    from frogsim.scenario.load import load_parameter_set
    from frogsim.scenario.fields import build
    j = [prm.path for prm in fitted.spec.parameters].index("muscle_force.slip_per_pressure")
    scale = 1500.0 / 630.0             # FESTO datasheets: DMSP-20 and DMSP-10 at 6 bar and 0 %
    law = build(MuscleForceLaw, load_parameter_set("fan2017-hysteresis")["muscle_force"], "muscle_force")
    assert law.hysteresis == "maxwell-slip"
    assert fitted.ci_low[j] * scale <= law.slip_per_pressure <= fitted.ci_high[j] * scale
    assert law.slip_per_pressure == pytest.approx(fitted.values[j] * scale, rel=0.02)
