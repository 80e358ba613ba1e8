"""The `control-tune` study: the gains of swim-board's six joint controllers searched in water
(Pareto front of tracking and air), the starting and tuned gains side by side in water and in
air. Checked: the front is the non-dominated set of the trials; the tuned gains are the member it
says; its runs reproduce the search's terms by their definition (mean RMS over the start's, air
over the start's); the setpoints drawn are the scenario's sines; the conclusion's verdicts follow
its numbers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from frogsim.studies.control_tune import CYCLES, JOINTS, SIDES, TRIALS, column


@pytest.fixture(scope="module")
def ct(study):
    return study("control-tune")


def dominates(a, b) -> bool:
    return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))


def test_the_front_is_the_non_dominated_set_of_the_trials(ct):
    s = ct.summary["control_tune"]
    pts = {t["trial"]: (t["tracking"], t["air"]) for t in s["pareto"]["trials"]}
    front = {f["trial"] for f in s["pareto"]["front"]}
    assert len(pts) == TRIALS and front <= set(pts)
    for f in front:
        assert not any(dominates(pts[o], pts[f]) for o in pts if o != f), f
    for o in set(pts) - front:
        assert any(dominates(pts[f], pts[o]) or pts[f] == pts[o] for f in front), o


def test_the_tuned_gains_are_the_best_tracking_member_at_no_more_air(ct):
    s = ct.summary["control_tune"]
    front = s["pareto"]["front"]
    pick = next(f for f in front if f["trial"] == s["tuned_trial"])
    within = [f for f in front if f["air"] <= 1.0]
    assert s["tuned_within_start_air"] == bool(within)
    assert pick["tracking"] == min(f["tracking"] for f in (within or front))


def test_the_runs_in_water_reproduce_the_searched_terms(ct):
    """tracking = the tuned run's mean RMS over the six joints / the start's (one kind); air = the
    air of the tuned run / the start's (same duration): the study's runs are the search's."""
    s = ct.summary["control_tune"]
    w = s["runs"]["water"]
    pick = next(f for f in s["pareto"]["front"] if f["trial"] == s["tuned_trial"])
    assert w["tuned"]["tracking_error_rms_deg_mean"] / w["start"]["tracking_error_rms_deg_mean"] == \
        pytest.approx(pick["tracking"], rel=1e-12)
    assert w["tuned"]["air_used_L_std"] / w["start"]["air_used_L_std"] == pytest.approx(pick["air"], rel=1e-12)


def test_the_tuned_gains_keep_left_equal_right_and_no_integral(ct):
    g = ct.summary["control_tune"]["tuned_gains"]
    for j in JOINTS:
        for n in ("proportional_gain", "derivative_gain", "co_contraction", "band", "integral_gain"):
            assert g[f"controllers.{j}_left.{n}"] == g[f"controllers.{j}_right.{n}"]
        assert float(g[f"controllers.{j}_left.integral_gain"].split()[0]) == 0.0


def test_the_setpoints_are_the_scenarios_sines_in_water_and_in_air(ct):
    """swim-board: the middle of each joint's range held until 0.5 s, then a 0.5 Hz sine of a
    quarter of the range (hip 41 deg: 20.5 +- 10.25 deg; knee, ankle 37 deg: 18.5 +- 9.25 deg)."""
    t = ct.table
    for env in ("water", "air"):
        sub = t[t["experiment"] == env]
        time = sub["time [s]"].to_numpy()
        assert time[-1] == pytest.approx(2.0 * CYCLES)
        for j, (mean, amp) in {"hip": (20.5, 10.25), "knee": (18.5, 9.25), "ankle": (18.5, 9.25)}.items():
            want = np.where(time < 0.5, mean, mean + amp * np.sin(2 * math.pi * 0.5 * (time - 0.5)))
            for side in SIDES:
                assert np.allclose(sub[column(f"{j}_{side}", "setpoint")].to_numpy(), want, atol=1e-9), (env, j)


def test_the_conclusion_says_what_the_numbers_say(ct):
    s = ct.summary["control_tune"]
    w, a = s["runs"]["water"], s["runs"]["air"]
    assert s["carries_over_to_air"] == (a["tuned"]["tracking_error_rms_deg_mean"]
                                        < a["start"]["tracking_error_rms_deg_mean"])
    for env, better in (("water", s["tuned_better_in_water"]), ("air", s["tuned_better_in_air"])):
        r = s["runs"][env]
        assert better == [j for j in JOINTS if r["tuned"]["joints_deg"][j] < r["start"]["joints_deg"][j]]
    text = s["conclusion"]
    for env in (w, a):
        assert (f"{env['start']['tracking_error_rms_deg_mean']:.2f} -> "
                f"{env['tuned']['tracking_error_rms_deg_mean']:.2f} deg") in text
    assert ("carry over to air on the mean" in text) == s["carries_over_to_air"]
    assert f"(trial {s['tuned_trial']}, the tuned gains)" in text
