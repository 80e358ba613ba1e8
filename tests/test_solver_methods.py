"""The integration methods (frogsim.engine.methods): chosen by name in [solver], the fixed-step
"rk4" at its order of convergence on a closed form and against the default method, the refusals,
and the registry (a throw-away method added to a copy of the package is one new module).

Reference values come from closed forms (Newton cooling of a closed rigid volume: an exponential)
and the order of the classical Runge-Kutta method (Hairer, Norsett and Wanner, Solving ODEs I,
Sec. II.1: global error O(h^4), so halving the step divides it by 2^4 = 16), not from the code's
own output.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import frogsim
from frogsim.engine import methods
from frogsim.errors import ScenarioError

from conftest import K_AIR, P_ATM, R_AIR, T_REF, one_muscle_scenario, steps
from tests.package_copy import package_copy, run_copy

PACKAGE = Path(frogsim.__file__).resolve().parent
CV = R_AIR / (K_AIR - 1.0)


def _cooling(method) -> dict:
    """A closed rigid 0.5 L source at 6 bar gauge and 353.15 K (valves shut all run, pump off)
    cooling to the 293.15 K wall: h A = 400 W/K, so tau = m c_v / (h A) ~ 6.2 ms."""
    d = one_muscle_scenario(steps((0.0, "hold")), 0.03, source={
        "volume": "0.5 L", "initial_pressure_gauge": "6 bar", "initial_temperature": "353.15 K",
        "heat_transfer_coefficient": "8000 W/(m^2*K)", "wall_area": "0.05 m^2"})
    d["solver"] = {"method": method}
    return d


def _cooling_closed_form(t):
    """p(t) of the closed rigid source (module docstring): T relaxes to the wall exponentially,
    p = m R T / V (mass and volume fixed)."""
    V, p0, T0 = 5e-4, P_ATM + 6e5, 353.15
    m = p0 * V / (R_AIR * T0)
    tau = m * CV / (8000.0 * 0.05)
    T = T_REF + (T0 - T_REF) * np.exp(-t / tau)
    return m * R_AIR * T / V, tau


def test_rk4_converges_at_its_order_on_a_closed_form():
    errors = []
    for step in (1.0, 0.5, 0.25):                 # ms, each a divisor of the 1 ms controller period
        res = frogsim.simulate(frogsim.load_scenario(_cooling({"name": "rk4", "step": f"{step} ms"})))
        p_exact, tau = _cooling_closed_form(res.t)
        assert res.stats["steps"] == round(30 / step) and res.stats["rejected"] == 0      # a fixed step: nothing rejected
        errors.append(np.max(np.abs(res.source_pressure - p_exact)))
    assert 0.15 < 1e-3 / tau < 0.17                         # h/tau = 0.16 at the coarsest step
    assert errors[0] > 1e-3 * 1e5 * 1e-6                      # far above rounding (~1e-10 bar)
    for coarse, fine in zip(errors, errors[1:]):
        assert 2 ** 4 * 0.8 < coarse / fine < 2 ** 4 * 1.25, errors       # 2^p, p = 4


def test_the_default_method_meets_the_same_closed_form_to_its_tolerance():
    res = frogsim.simulate(frogsim.load_scenario(_cooling("dopri-rosenbrock")))
    p_exact, _ = _cooling_closed_form(res.t)
    np.testing.assert_allclose(res.source_pressure, p_exact, rtol=1e-6)


def _charge_hold_vent(method, rtol=1e-10, duration=0.6):
    """One hip muscle charged, held and vented at a fixed length (the source 6 bar gauge)."""
    d = one_muscle_scenario(steps((0.0, "charge"), (0.2, "hold"), (0.3, "vent")), duration)
    d["solver"] = {"method": method, "rtol": rtol}
    return frogsim.simulate(frogsim.load_scenario(d))


def test_rk4_agrees_with_the_default_within_a_tolerance_of_its_order():
    # the default method at rtol 1e-12 (its own error here ~1e-5 Pa) is the reference. rk4's
    # error is O(h^4) where the right-hand side is smooth, but the valves' flow law (ISO 6358,
    # Eq. (8): a square root of the pressure difference near equal pressures) is not smooth where
    # the venting muscle meets the exhaust pressure, and there a fixed-step method keeps an order
    # of about 2 (the error then depends on where the grid falls in that layer, not as h^4). So the
    # tolerance is an order-2 bound, 1 Pa (1e-5 bar) at the controller period 1 ms, falling as
    # (h / 1 ms)^2; measured: 0.066, 0.030, 0.017, 0.0013 Pa at 1, 0.5, 0.25, 0.1 ms
    ref = _charge_hold_vent("dopri-rosenbrock", rtol=1e-12)
    for step in (1.0, 0.5, 0.25, 0.1):
        res = _charge_hold_vent({"name": "rk4", "step": f"{step} ms"})
        assert np.array_equal(res.t, ref.t)
        diff = np.max(np.abs(res.muscle_pressure("m0") - ref.muscle_pressure("m0")))
        assert diff < 1.0 * step ** 2, (step, diff)
    # while the valve is choked (the charge) the flow does not depend on the muscle's pressure and
    # the solution is near a straight line in time: rk4 meets the reference to rounding there
    res = _charge_hold_vent({"name": "rk4", "step": "1 ms"})
    charge = ref.t < 0.1
    assert np.max(np.abs(res.muscle_pressure("m0") - ref.muscle_pressure("m0"))[charge]) < 1e-6


def test_the_batched_engine_runs_the_scenarios_method():
    # variants of an rk4 scenario, one with another step, through the batched engine: each run is
    # the one frogsim.simulate makes of the same scenario, bit for bit
    from frogsim.engine.batch import build_models, run_models
    d = one_muscle_scenario(steps((0.0, "charge"), (0.05, "vent")), 0.1)
    d["solver"] = {"method": {"name": "rk4", "step": "0.25 ms"}}
    base = frogsim.load_scenario(d)
    points = [{"solver.method.step": 2.5e-4}, {"solver.method.step": 5e-4}]
    batch = run_models(build_models(base, points), threads=1)
    for pt, res in zip(points, batch):
        alone = frogsim.simulate(base.replace(pt))
        assert np.array_equal(res.y, alone.y) and np.array_equal(res.u, alone.u)
    assert not np.array_equal(batch[0].y, batch[1].y)          # the step is the run's own


def test_method_by_name_and_its_refusals():
    sc = frogsim.load_scenario(one_muscle_scenario(steps((0.0, "hold")), 0.01))
    assert sc.solver.method.name == methods.DEFAULT == "dopri-rosenbrock"
    d = one_muscle_scenario(steps((0.0, "hold")), 0.01)
    d["solver"] = {"method": "rk4"}
    assert frogsim.load_scenario(d).solver.method.step == pytest.approx(1e-4)
    d["solver"] = {"method": "rk5"}
    with pytest.raises(ScenarioError) as e:
        frogsim.load_scenario(d)
    assert e.value.field == "solver.method" and "'dopri-rosenbrock', 'rk4'" in str(e.value)
    d["solver"] = {"method": {"name": "rk4", "step": "0.3 ms"}}
    with pytest.raises(ScenarioError) as e:
        frogsim.load_scenario(d)
    assert e.value.field == "solver.method.step"
    assert "0.3 ms" in str(e.value) and "must divide the controller period 1 ms" in str(e.value)
    d["solver"] = {"method": {"name": "rk4", "stepp": "0.1 ms"}}
    with pytest.raises(ScenarioError) as e:
        frogsim.load_scenario(d)
    assert e.value.field.startswith("solver.method")
    # a variant: the step is a variable path, checked as the loader checks it
    d["solver"] = {"method": "rk4"}
    sc = frogsim.load_scenario(d)
    assert "solver.method.step" in sc.variable_paths()
    assert sc.replace({"solver.method.step": 2.5e-4}).solver.method.step == 2.5e-4
    with pytest.raises(ScenarioError, match="solver.method.step"):
        sc.replace({"solver.method.step": 3e-4})


def test_the_cli_refuses_a_fixed_step_in_one_line(tmp_path):
    scen = tmp_path / "bad.toml"
    scen.write_text(textwrap.dedent('''
        name = "bad"
        parameters = "fan2017"
        duration = "0.01 s"
        [solver]
        method = { name = "rk4", step = "0.3 ms" }
        [muscles.hip]
        type = "hip"
        motion = { kind = "constant" }
        program = { steps = [ { at = "0 s", state = "hold" } ] }
    '''))
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "frogsim", "simulate", str(scen), "--out", str(out)],
                          capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, PYTHONPATH=str(PACKAGE.parent)))
    assert done.returncode == 2, done.stderr[-2000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "solver.method.step" in lines[0] and "Traceback" not in done.stderr, done.stderr
    assert not out.exists()


# --- the registry: a new method is one new module ---------------------------------------------------------
EULER = '''
"""Integration method "euler": explicit Euler at a fixed step (a throw-away method of the tests)."""
from __future__ import annotations

from dataclasses import dataclass

from frogsim._jit import jit_inner
from frogsim.circuit.rhs import rhs
from frogsim.engine.methods.spec import IntegrationMethod, StepControl
from frogsim.engine.stepsize import accepted_fixed, propose_grid, rejected_fixed
from frogsim.scenario.fields import quantity
from frogsim.scenario.methods import MethodSettings

CODE = {code!r}


@dataclass(frozen=True)
class EulerSettings(MethodSettings):
    METHOD = {name!r}
    step: float = quantity("time", gt=0.0, le=0.1, display="ms", default=1e-4)

    def params(self):
        return (self.step,)


@jit_inner
def step(t, h, t_new, y, f, yn, fn, u, pump_on, model, atol, rtol, par, ds, own, rc, mat, kmat, kvec, aux, work, stats):
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    for j in range(y.size):
        yn[j] = y[j] + h * f[j]
    rhs(t_new, yn, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, fn, aux, work)
    stats[2] += 1
    return 0.0, 0.0, 0.0, False


@jit_inner
def dense(h, y, yn, f, fn, own, rc1, rc2, rc3, rc4):
    for j in range(y.size):
        rc1[j] = yn[j] - y[j]
        rc2[j] = 0.0
        rc3[j] = 0.0
        rc4[j] = 0.0


METHOD = IntegrationMethod(settings=EulerSettings, code=CODE, step=step, dense=dense,
                           control=StepControl(propose=propose_grid, accepted=accepted_fixed,
                                               rejected=rejected_fixed),
                           order=1, vectors=0)
'''


def _package_copy(root: Path, modules: dict) -> Path:
    """A copy of the package under root/src with ``modules`` ({file name: text}) added to
    engine/methods/ (:func:`tests.package_copy.package_copy`). Returns root/src."""
    return package_copy(root, {f"engine/methods/{name}": text for name, text in modules.items()})


def _run_copy(src: Path, code: str, cwd: Path, timeout: float = 900):
    return run_copy(src, "-c", code, cwd=cwd, timeout=timeout)


@pytest.mark.parametrize("case", ["code", "name", "no-declaration", "signature"])
def test_the_registry_refuses_a_duplicate_or_undeclared_method(tmp_path, case):
    if case == "signature":             # a step without the driver's last argument (stats)
        module = EULER.format(code=9.0, name="euler").replace("aux, work, stats):", "aux, work):")
    elif case == "code":
        module = EULER.format(code=2.0, name="euler")
    elif case == "name":
        module = EULER.format(code=9.0, name="rk4")
    else:
        module = EULER.format(code=9.0, name="euler").split("\nMETHOD = ")[0]
    src = _package_copy(tmp_path, {"added.py": module})
    done = _run_copy(src, "import frogsim", tmp_path, timeout=120)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: integration methods: "), done.stderr[-2000:]
    # the modules are imported in the order of their file names: added.py before rk4.py
    if case == "code":
        assert "CODE 2.0 of frogsim.engine.methods.rk4 (method 'rk4') is already taken by " \
               "frogsim.engine.methods.added (method 'euler')" in last, last
    elif case == "name":
        assert "method name 'rk4' of frogsim.engine.methods.rk4 is already taken by " \
               "frogsim.engine.methods.added" in last, last
    elif case == "signature":
        assert "method 'euler''s step takes 21 arguments (t, h, " in last and "the driver passes 22: " in last, last
    else:
        assert "declares no METHOD = IntegrationMethod" in last, last
