"""A new member of each family is one new module: an actuator type, a valve type (and the
controllers' view of it), a sensor type, two controller kinds and an integration method, added
together to one copy of the package in which no file is edited, each then run against a closed
form or its own declared behaviour (docs/architecture.md, "Families").

The members' modules are the family tests' throw-away ones (tests/test_*_family.py,
test_controller_kinds.py, test_solver_methods.py). One copy holds them all, so the engine is
compiled into the copy's Numba cache once for every test here."""
from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from tests.package_copy import changed_files, package_copy, run_copy
from tests.test_actuator_family import ACTUATOR_MODULE, ACTUATOR_RUN
from tests.test_controller_kinds import FIXED_DUTY, RUN as KIND_RUN, _kind_module
from tests.test_sensor_family import SENSOR_MODULE, SENSOR_RUN
from tests.test_solver_methods import EULER, _cooling, _cooling_closed_form
from tests.test_valve_family import VALVE_MODULE, VALVE_RUN

BAR = 1e5

#: path inside the package -> the new member's module
MEMBERS = {
    "circuit/actuators/bellows.py": ACTUATOR_MODULE.format(code=9.0),
    "circuit/valves/throttled.py": VALVE_MODULE.format(code=9.0),
    "circuit/sensors/rounding.py": SENSOR_MODULE.format(code=9.0),
    "control/kinds/vent_always.py": _kind_module("vent-always", 9.0, "VentAlwaysSettings"),
    "control/kinds/fixed_duty.py": FIXED_DUTY,
    "engine/methods/euler.py": EULER.format(code=9.0, name="euler"),
}


@pytest.fixture(scope="module")
def copy(tmp_path_factory):
    """root/src of one copy of the package with every member of :data:`MEMBERS` added."""
    return package_copy(tmp_path_factory.mktemp("members"), MEMBERS)


def _run(copy, code: str, tmp_path, timeout: float = 1800) -> dict:
    """The last line of ``python -c code`` run in a fresh folder on the copy, as JSON."""
    work = tmp_path / "run"
    work.mkdir()
    done = run_copy(copy, "-c", code, cwd=work, timeout=timeout)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1]), work


def test_the_members_are_new_modules_and_nothing_else_differs(copy):
    assert changed_files(copy) == sorted(MEMBERS)


def test_a_new_actuator_type_is_one_new_module(copy, tmp_path):
    """A "bellows" actuator type (V = A L, F = p A): a muscle type naming it starts with the volume
    A L0 plus its dead volume, charged from the source it ends at the source's pressure (the
    circuit's invariant), and pulls p_gauge A."""
    out, _ = _run(copy, ACTUATOR_RUN, tmp_path)
    A = 8e-4
    assert out["V0"] == pytest.approx(A * out["L0"] + out["dead"], rel=1e-12)
    assert out["p_end"] == pytest.approx(out["ps_end"], rel=1e-4)
    assert out["T_end"] == pytest.approx((out["p_end"] - out["patm"]) * A, rel=1e-9)


def test_a_new_valve_type_is_one_new_module(copy, tmp_path):
    """A "throttled" valve type: an open-loop charge through it is Eq. (8) choked at its own
    conductance (half the MHJ9's), and a bang-bang controller drives it through its controller view
    to the setpoint."""
    out, _ = _run(copy, VALVE_RUN, tmp_path)
    t, q = np.array(out["t"]), np.array(out["q"])
    i1 = int(np.searchsorted(t, 0.5e-3 - 1e-12))
    assert q[i1] / t[i1] == pytest.approx(0.2e-8 * out["rho"] * out["p_s"], rel=2e-3)
    assert abs(out["p_end"] - 3e5) < 0.1e5
    assert out["rms"] < 0.1


def test_a_new_sensor_type_is_one_new_module(copy, tmp_path):
    """A "rounding" pressure sensor: registered, its line written by its own block, its integer form
    reached through the family's compiled dispatch (300488.28 Pa on a 0-5 V line of 10 bar span at
    10 bits: 1.5024414 V x 1024 / 5 V = 307.70, rounded 308 where the ADC's truncation gives 307),
    the shipped transducer's unchanged (348: 0.5 V + 1.2 V at 3 bar on 0.5-4.5 V over 10 bar).
    Chosen by name in hold-3bar's [firmware] (``transducer = { type = "rounding", ... }``), its
    code is in the model's firmware row, the board's count of the muscle is its own (308 against
    the transducer's 348 at 300488.28 Pa: floor(1.70195 V x 204.8) = 348), and bang-bang on it
    holds the muscle at the 3 bar setpoint to within its 0.1 bar band's width."""
    out, _ = _run(copy, SENSOR_RUN, tmp_path)
    assert {k: out[k] for k in ("module", "quantity", "c", "t")} == {
        "module": "frogsim.circuit.sensors.rounding", "quantity": "pressure", "c": 308, "t": 348}
    assert {k: out["rounding"][k] for k in ("type", "code", "count")} == {"type": "rounding", "code": 9.0, "count": 308}
    assert {k: out["transducer"][k] for k in ("type", "code", "count")} == {"type": "transducer", "code": 1.0,
                                                                            "count": 348}
    for name in ("rounding", "transducer"):
        assert abs(out[name]["p_end"] - 3 * BAR) < 0.1 * BAR, out


def test_a_new_kind_is_one_new_module(copy, tmp_path):
    """Two kinds: a "vent-always" law (no firmware twin) vents its muscle from the first sample on,
    down to the exhaust's pressure; a "fixed-duty" law keeps its charge valve open its duty's
    fraction of the time, in simulate and in a sweep; `frogsim firmware` refuses the vent-always
    scenario by name."""
    out, work = _run(copy, KIND_RUN, tmp_path)
    v = out["vent"]
    t = np.array(v["t"])
    # the command of sample 0 acts one dead time later: from then on the discharge valve is open,
    # the charge valve never opens
    assert not any(v["charge"])
    assert np.all(np.array(v["discharge"])[t > v["dead"] + 1e-9] == 1.0)
    assert np.all(np.array(v["discharge"])[t < v["dead"] - 1e-9] == 0.0)
    assert v["switchings"] == [0, 1]
    p, pe = np.array(v["p"]), np.array(v["p_exhaust"])
    assert p[0] - v["patm"] == pytest.approx(3e5)
    # vented, the muscle ends at the exhaust's pressure (the circuit's invariant), falling all the way
    assert abs(p[-1] - pe[-1]) < 0.01 * BAR
    assert np.all(np.diff(p) <= 1e-6 * BAR)
    assert not any(key.startswith("tracking") for key in v["metrics"])      # it tracks nothing
    # fixed-duty, no dead time: the charge valve is open 3 of every 10 samples (1 ms each), vent the other 7
    assert out["charge_fraction"] == pytest.approx(0.3, abs=0.01)
    assert not out["vent_and_charge_together"]
    assert abs(out["switchings"][0] - 2 * 50) <= 1      # 50 periods of 10 ms: it opens and closes once in each
    # the sweep's points are the single runs (air charged over the run, a standard volume [m^3])
    np.testing.assert_allclose(out["sweep"], out["single"], rtol=1e-12)
    assert out["sweep"][1] > out["sweep"][0] > 0.0     # more duty, more air
    # frogsim firmware: exit 2, one line naming the controller and its kind, no folder
    fw = out["firmware"]
    assert fw["code"] == 2, fw["stderr"]
    err = fw["stderr"].strip()
    assert len(err.splitlines()) == 1 and err.startswith("frogsim: error: "), err
    assert "controllers.vent.kind = 'vent-always'" in err and "no firmware twin" in err, err
    assert not (work / "fw").exists()


def test_a_new_method_is_one_new_module(copy, tmp_path):
    """Explicit Euler at a fixed step, on the closed rigid source cooling to its wall
    (tests/test_solver_methods.py): its fixed grid, and its error halving with the step (order 1)
    against the closed form."""
    code = textwrap.dedent('''
        import json
        import frogsim
        out = {{}}
        for step, scenario in {scenarios!r}.items():
            r = frogsim.simulate(frogsim.load_scenario(scenario))
            out[step] = {{"t": r.t.tolist(), "p": r.source_pressure.tolist(), "steps": int(r.stats["steps"])}}
        print(json.dumps(out))
    ''').format(scenarios={s: _cooling({"name": "euler", "step": f"{s} ms"}) for s in ("0.5", "0.25")})
    out, _ = _run(copy, code, tmp_path)
    errors = []
    for s in ("0.5", "0.25"):
        t, p = np.array(out[s]["t"]), np.array(out[s]["p"])
        errors.append(float(np.max(np.abs(p - _cooling_closed_form(t)[0]))))
    assert (out["0.5"]["steps"], out["0.25"]["steps"]) == (60, 120)   # its fixed grid: 30 ms in 0.5 and 0.25 ms steps
    assert 2 ** 1 * 0.8 < errors[0] / errors[1] < 2 ** 1 * 1.25, errors      # explicit Euler: order 1
