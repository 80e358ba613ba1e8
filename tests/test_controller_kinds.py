"""Controller kinds: one module each, found through the registry; their settings checked like any
other field (units by dimension, ranges that make physical sense); a Python law's metrics carry
its own label and setpoint; the registry refuses two kinds with one code or name, a code no kind
declares stops a run instead of holding the valves, `frogsim firmware` refuses a kind without a
firmware twin, and a new kind is one new module, nothing else edited."""
from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import frogsim
from frogsim.errors import ScenarioError
from tests.conftest import P_ATM
from tests.package_copy import PACKAGE, package_copy, run_copy as _run_copy
from tests.test_control import closed_loop

BAR = 1e5


# --- units by dimension ------------------------------------------------------------------------------
def test_a_gain_per_radian_refuses_a_pressure():
    """pint counts the radian as no unit; "30 bar" for a gain in bar/rad is 30 bar, not 30 bar/rad."""
    from frogsim.scenario.units import to_si
    with pytest.raises(ScenarioError, match=r"proportional_gain = '30 bar'.*per angle"):
        to_si("30 bar", "pressure_per_angle", "controllers.hip.proportional_gain")
    assert to_si("30 bar/rad", "pressure_per_angle", "x") == pytest.approx(30e5)
    assert to_si("1 bar/deg", "pressure_per_angle", "x") == pytest.approx(1e5 * 180 / math.pi)
    with pytest.raises(ScenarioError, match="must be an angle"):
        to_si("25", "angle", "muscle_types.hip.rest_angle")
    with pytest.raises(ScenarioError, match="must not hold an angle"):
        to_si("0.3 rad", "dimensionless", "muscle_types.hip.max_contraction")


def test_a_joint_angle_gain_written_in_bar_is_refused_by_the_loader():
    raw = {"controllers": {"hip": {"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg",
                                   "proportional_gain": "30 bar"}}}
    with pytest.raises(ScenarioError, match=r"controllers\.hip\.proportional_gain"):
        frogsim.load_robot_scenario(_robot_with(raw))


def _robot_with(extra: dict) -> dict:
    from frogsim.scenario.load import merged_raw
    raw, _ = merged_raw("hip-angle-in-air")
    raw = dict(raw)
    raw.update(extra)
    return raw


# --- ranges that make physical sense ---------------------------------------------------------------
def test_a_pwm_minimum_pulse_must_be_shorter_than_its_period():
    # 20 Hz: a 50 ms period; a 1 s minimum pulse would drop every pulse
    with pytest.raises(ScenarioError, match=r"controllers\.loop\.minimum_pulse = 1000 ms: must be shorter than the period \(50 ms"):
        frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "minimum_pulse": "1 s"}))
    with pytest.raises(ScenarioError, match="minimum_pulse"):
        frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "minimum_pulse": "50 ms"}))
    frogsim.load_scenario(closed_loop({"kind": "pwm", "duty": 0.3, "minimum_pulse": "49 ms"}))


@pytest.mark.parametrize("sensor", ["sensor", "angle_sensor"])
def test_sensor_bits_are_at_least_one(sensor):
    if sensor == "sensor":
        with pytest.raises(ScenarioError, match=r"controllers\.loop\.sensor\.bits = 0: must be >= 1"):
            frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "sensor": {"bits": 0}}))
        sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "sensor": {"bits": 1}}))
        assert sc.controllers["loop"].sensor.bits == 1
        with pytest.raises(ScenarioError, match="must be >= 1"):
            sc.replace({"controllers.loop.sensor.bits": 0})
    else:
        raw = {"controllers": {"hip": {"kind": "joint-angle", "joint": "hip_left", "setpoint": "20 deg",
                                       "angle_sensor": {"bits": 0}}}}
        with pytest.raises(ScenarioError, match=r"controllers\.hip\.angle_sensor\.bits = 0: must be >= 1"):
            frogsim.load_robot_scenario(_robot_with(raw))


def test_settle_must_lie_inside_the_run():
    with pytest.raises(ScenarioError, match=r"controllers\.loop\.settle = 0\.5 s: must be shorter than the run"):
        frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "settle": "0.5 s"}, 0.3))
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "settle": "0.1 s"}, 0.3))
    with pytest.raises(ScenarioError, match="shorter than the run"):
        sc.replace({"controllers.loop.settle": 0.3})
    with pytest.raises(ScenarioError, match="shorter than the run"):
        sc.replace({"duration": 0.05})


def test_a_short_run_without_a_written_settle_still_has_tracking_metrics():
    """Unwritten, settle is 0.2 s, or a tenth of a run not longer: a 0.1 s run counts from 0.01 s on
    (so its metrics are numbers, never a silent null)."""
    long = frogsim.simulate(frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar"}, 1.0)))
    assert long.control_metrics()["loop"]["settle_s"] == 0.2
    r = frogsim.simulate(frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar"}, 0.1)))
    m = r.control_metrics()["loop"]
    assert m["settle_s"] == pytest.approx(0.01)
    e = r.setpoint("loop") - r.muscle_pressure("hip")
    assert np.allclose(r.setpoint("loop"), P_ATM + 3e5, rtol=0, atol=1e3)
    after = e[r.t >= m["settle_s"]]
    assert after.size == r.t.size - 10                      # rows from 0.01 s on
    assert m["tracking_error_rms_bar"] == pytest.approx(np.sqrt(np.mean(after ** 2)) / 1e5)


# --- setpoint tables: read once, at load time ---------------------------------------------------------
def test_a_table_setpoint_is_read_once_by_the_loader_and_hashed_for_the_manifest(tmp_path, monkeypatch):
    import hashlib
    from frogsim.sweep.spec import describe_inputs, input_files
    csv = tmp_path / "sp.csv"
    csv.write_bytes(b"time_s,pressure_bar\n0,1\n0.1,3\n")
    monkeypatch.chdir(tmp_path)
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": {"kind": "table", "file": "sp.csv"},
                                            "settle": "0.05 s"}, 0.2))
    sp = sc.controllers["loop"].setpoint
    assert sp.knots == ((0.0, 1e5), (0.1, 3e5))             # bar gauge -> Pa gauge
    sha = hashlib.sha256(b"time_s,pressure_bar\n0,1\n0.1,3\n").hexdigest()
    assert sp.digest == sha
    described = {d["role"]: d["sha256"] for d in describe_inputs(input_files(sc))}
    assert described["controllers.loop.setpoint.file"] == sha
    csv.unlink()              # nothing reads the file again: not the rules, the model or a variant
    r = frogsim.simulate(sc.replace({"controllers.loop.band": 0.2e5}))
    # the run follows the table: 1 bar gauge at first, 3 bar gauge from 0.1 s on (within the band)
    p = r.muscle_pressure("hip") - P_ATM
    assert abs(p[-1] - 3e5) < 0.2e5


# --- a Python law's metrics ---------------------------------------------------------------------------
def test_python_law_metrics_carry_its_label_and_its_setpoint():
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar", "settle": "0.1 s"}, 0.3))

    def vent(t, obs):
        return {"hip": "vent"}

    m = frogsim.simulate(sc, controller=vent).control_metrics()["loop"]
    assert m["kind"] == "python:vent"
    assert "tracking_error_rms_bar" not in m        # no setpoint given: none measured
    assert m["switchings"]["hip"]["charge"] == 0 and m["air_used_L_std"] == 0.0

    class Hold:
        label = "hold-at-atmosphere"

        def setpoint(self, t):
            return P_ATM + 1.0 * BAR          # 1 bar gauge

        def __call__(self, t, obs):
            return {"hip": "hold"}

    r = frogsim.simulate(sc, controller=Hold())
    m = r.control_metrics()["loop"]
    assert m["kind"] == "hold-at-atmosphere"
    # the muscle starts at the atmosphere and is held there: 1 bar below the law's setpoint
    p = r.muscle_pressure("hip")
    np.testing.assert_allclose(p, P_ATM, rtol=1e-9)
    assert m["tracking_error_rms_bar"] == pytest.approx(1.0, rel=1e-6)
    assert m["tracking_error_max_bar"] == pytest.approx(1.0, rel=1e-6)


# --- the registry ------------------------------------------------------------------------------------
def test_the_registry_finds_every_shipped_kind_and_the_loader_knows_the_same_names():
    from frogsim.control import kinds
    from frogsim.scenario.kinds import KINDS as LOADER
    shipped = {"bang-bang": 2.0, "joint-angle": 6.0, "program": None, "pwm": 3.0, "sliding-mode": 4.0, "pid": 10.0}
    assert {k.name: k.code for k in kinds.KINDS.values() if k.name in shipped} == shipped
    assert list(LOADER) == list(kinds.KINDS)
    assert all(LOADER[n] is k.settings for n, k in kinds.KINDS.items())
    # each shipped kind has a twin; the C defines them program first, then by code
    twins = [k.name for k in kinds.with_twin() if k.name in shipped]         # pid has none (no DAC on the board)
    assert twins == ["program", "bang-bang", "pwm", "sliding-mode", "joint-angle"]


def test_every_firmware_twin_is_checked_against_its_c():
    """tests/test_firmware_laws.py runs each kind's C twin beside its Numba twin (``_both(lib,
    module, ...)`` on random inputs): a kind whose twin has no such test fails here."""
    from frogsim.control import kinds
    text = (Path(__file__).with_name("test_firmware_laws.py")).read_text()
    for k in kinds.with_twin():
        module = k.module.rsplit(".", 1)[1]
        assert f"_both(lib, {module}," in text, f"kind {k.name!r}: no twin test in tests/test_firmware_laws.py"


def test_a_row_whose_code_no_kind_declares_stops_the_run_instead_of_holding():
    """The dispatch has no fallback: a row of code 9 (no kind's) is an error, not a hold."""
    from frogsim.circuit.model import build_model
    from frogsim.control.table import L_KIND
    sc = frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar"}, 0.05))
    model = build_model(sc)
    row = [c for c in range(model.laws.shape[0]) if model.laws[c, L_KIND] == 2.0]
    assert len(row) == 1
    model.laws[row[0], L_KIND] = 9.0
    with pytest.raises(ValueError, match="kind code that no controller kind declares"):
        frogsim.simulate(model)


def test_a_firmware_block_whose_code_has_no_twin_is_an_error():
    """The plan's twin of hold-3bar (bang-bang, code 2) at a count inside the sensor's range (no
    fault: the law runs), then the same block under code 9 (no kind's): an error, not a hold."""
    from frogsim.control import firmware as fwm
    plan = fwm.firmware_plan(frogsim.load_scenario("hold-3bar"))
    codes, *rest = fwm._packed(plan)
    assert list(codes) == [2.0]
    adc = np.array([100.0])           # 0.49 V: well below 3 bar, inside the fault limits: charge
    out = np.zeros(1, np.int8)
    fwm._plan_modes(codes, *rest, -1.0, 10.0, fwm.firmware_memory(plan), 0, adc, out)
    assert out[0] == 1
    with pytest.raises(ValueError, match="no controller kind's with a firmware twin"):
        fwm._plan_modes(np.array([9.0]), *rest, -1.0, 10.0, fwm.firmware_memory(plan), 0, adc, out)


def test_firmware_refuses_a_kind_without_a_twin_naming_the_controller_and_the_kind(tmp_path, monkeypatch, capsys):
    """bang-bang declared without its twin (as a kind that has none): `frogsim firmware` on
    hold-3bar (controller "hold") exits 2 with one line and writes nothing."""
    from frogsim.cli import main
    from frogsim.control import kinds
    monkeypatch.setitem(kinds.KINDS, "bang-bang", dataclasses.replace(kinds.KINDS["bang-bang"], firmware=None))
    out = tmp_path / "fw"
    code = main(["firmware", "hold-3bar", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "controllers.hold.kind = 'bang-bang'" in err and "controller 'hold'" in err, err
    assert "no firmware twin" in err, err
    assert not out.exists()


# --- what a search reads: the tunable gains -----------------------------------------------------------
def test_a_gain_range_is_converted_by_its_unit():
    from frogsim.control.kinds import bang_bang, sliding_mode, spec
    assert spec.Gain("band", "bar", 0.01, 1.0, log=True).bounds(bang_bang.BangBangSettings) == \
        pytest.approx((1e3, 1e5))                          # 1 bar = 1e5 Pa
    assert spec.Gain("horizon", "ms", 0.2, 20.0).bounds(sliding_mode.SlidingModeSettings) == \
        pytest.approx((2e-4, 2e-2))
    with pytest.raises(ValueError, match="not a quantity setting"):
        spec.Gain("sensor", "bar", 0.1, 1.0).bounds(bang_bang.BangBangSettings)
    with pytest.raises(ScenarioError, match="expected a pressure"):
        spec.Gain("band", "ms", 0.1, 1.0).bounds(bang_bang.BangBangSettings)


def _scenario_of(kind: str, duration: float = 1.0):
    if kind == "joint-angle":
        return frogsim.load_robot_scenario("hip-angle-in-air").pneumatic, "hip"
    # pid commands a proportional valve's spool (valve type "proportional")
    extra = {"valves": {"type": "proportional"}} if kind == "pid" else {}
    return frogsim.load_scenario(closed_loop({"kind": kind, "setpoint": "3 bar"}, duration, **extra)), "loop"


@pytest.mark.parametrize("kind", ["bang-bang", "pwm", "sliding-mode", "joint-angle", "pid"])
def test_every_gain_range_holds_the_shipped_default_and_the_loader_takes_its_ends(kind):
    """A search may start from the default and propose any value of the ranges: all gains at
    their lows at once, and at their highs, pass every rule (bounds, cross-field checks)."""
    from frogsim.control import kinds
    declared = kinds.KINDS[kind]
    assert declared.gains, kind
    sc, name = _scenario_of(kind)
    fields = {f.name: f for f in dataclasses.fields(declared.settings)}
    lows, highs = {}, {}
    for g in declared.gains:
        lo, hi = g.bounds(declared.settings)
        default = fields[g.name].default
        assert lo <= default <= hi, (g, default)
        assert lo > 0.0 or not g.log
        lows[g.path(name)], highs[g.path(name)] = lo, hi
    for values in (lows, highs):
        varied = sc.replace(values)
        for path, v in values.items():
            assert getattr(varied.controllers[name], path.rsplit(".", 1)[1]) == v


def test_the_program_kind_has_no_row_nothing_to_tune_and_no_metrics():
    from frogsim.control import kinds
    k = kinds.KINDS["program"]
    assert (k.code, k.law, k.gains, k.metrics, k.tracks) == (None, None, (), (), None)


# --- what the engines read: setpoint and metrics ------------------------------------------------------
#: the keys every closed-loop controller's metrics carry, whatever its kind
COMMON = {"kind", "muscles", "joint", "settle_s", "switchings", "switchings_per_s", "air_used_L_std"}


@pytest.mark.parametrize("kind", ["bang-bang", "pwm", "sliding-mode", "pid"])
def test_a_pressure_kind_reports_the_metrics_it_declares(kind):
    from frogsim.control import kinds
    from frogsim.scenario.kinds import ControllerSettings
    r = frogsim.simulate(_scenario_of(kind, 0.3)[0])
    entry = r.control_metrics()["loop"]
    declared = kinds.KINDS[kind]
    assert set(entry) - COMMON == set(declared.metrics)
    assert declared.tracks == "pressure"
    assert ControllerSettings().setpoint is None            # the base class declares it
    assert r.model.scenario.controllers["loop"].setpoint.value == pytest.approx(3 * BAR)


def test_the_joint_angle_kind_reports_the_metrics_it_declares():
    from frogsim.control import kinds
    r = frogsim.swim("hip-angle-in-air")
    entry = r.control_metrics()["hip"]
    declared = kinds.KINDS["joint-angle"]
    assert set(entry) - COMMON == set(declared.metrics)
    assert declared.tracks == "angle"


# --- adding a kind: one new module, nothing else edited -----------------------------------------------
def _package_copy(root: Path, modules: dict) -> Path:
    """A copy of the package under root/src with ``modules`` ({file name: text}) added to
    control/kinds/ (:func:`tests.package_copy.package_copy`). Returns root/src."""
    return package_copy(root, {f"control/kinds/{name}": text for name, text in modules.items()})


KIND_MODULE = '''
"""Kind {name!r}: a throw-away law (tests): vent at every sample; no firmware twin."""
from __future__ import annotations

from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.kinds.spec import ControllerKind
from frogsim.control.signals import MODE_VENT
from frogsim.control.table import valve_row

CODE = {code!r}


@dataclass(frozen=True)
class {cls}(SensedLoop):
    KIND = {name!r}

    def write_rows(self, name, ctx):
        return [valve_row(ctx, CODE, self.muscle, self.sensor)]


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    return MODE_VENT
{declaration}'''
DECLARED = "\n\nKIND = ControllerKind(settings={cls}, code=CODE, law=law, firmware=None, tracks=None)\n"


def _kind_module(name: str, code: float, cls: str = "Settings", declared: bool = True) -> str:
    return KIND_MODULE.format(code=code, cls=cls, name=name, declaration=DECLARED.format(cls=cls) if declared else "")


@pytest.mark.parametrize("case", ["code", "name", "undeclared"])
def test_the_registry_refuses_a_duplicate_code_or_name_naming_both_modules(tmp_path, case):
    """A module added to a copy of the package with bang-bang's CODE 2.0, or its name, or settings
    without their declaration: importing frogsim fails (ImportError) naming the modules; with a
    code and a name of its own, the same module is a kind."""
    module = {"code": _kind_module("twin-code", 2.0), "name": _kind_module("bang-bang", 7.0),
              "undeclared": _kind_module("undeclared", 7.0, declared=False)}[case]
    src = _package_copy(tmp_path / "bad", {"added.py": module})
    done = _run_copy(src, "-c", "import frogsim", cwd=tmp_path)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: controller kinds: "), done.stderr[-2000:]
    assert "frogsim.control.kinds.added" in last
    # the modules are imported in the order of their file names: added.py first, bang_bang.py refused
    if case == "code":
        assert "CODE 2.0 of frogsim.control.kinds.bang_bang (kind 'bang-bang') is already taken by " \
               "frogsim.control.kinds.added (kind 'twin-code')" in last, last
    elif case == "name":
        assert "kind name 'bang-bang' of frogsim.control.kinds.bang_bang is already taken by " \
               "frogsim.control.kinds.added" in last, last
    else:
        assert "declares no KIND = ControllerKind" in last, last
    ok = _package_copy(tmp_path / "ok", {"added.py": _kind_module("vent-always", 9.0)})
    done = _run_copy(ok, "-c", "import frogsim.control.kinds as k; print(k.KINDS['vent-always'].module)",
                     cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "frogsim.control.kinds.added"


FIXED_DUTY = '''
"""Kind "fixed-duty": a throw-away law (tests): charge for the first round(duty N) samples of each
period of N samples, vent for the rest."""
from __future__ import annotations

import math
from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.kinds.spec import ControllerKind, Gain
from frogsim.control.signals import B_PHASE, MODE_CHARGE, MODE_VENT
from frogsim.control.table import L_DUTY, L_PERIOD_N, valve_row
from frogsim.scenario.fields import integer, quantity

CODE = 8.0


@dataclass(frozen=True)
class FixedDutySettings(SensedLoop):
    KIND = "fixed-duty"
    duty: float = quantity("dimensionless", ge=0.0, le=1.0, display="%", default=0.5)
    period_samples: int = integer(ge=1, le=10000, default=10)

    def write_rows(self, name, ctx):
        row = valve_row(ctx, CODE, self.muscle, self.sensor)
        row[L_DUTY] = self.duty
        row[L_PERIOD_N] = self.period_samples
        return [row]


@jit
def law(laws, mp, c, cs, b, y, p, ts):
    N = int(laws[c, L_PERIOD_N])
    phase = int(cs[b + B_PHASE])
    cs[b + B_PHASE] = float((phase + 1) % N)
    return MODE_CHARGE if phase < math.floor(laws[c, L_DUTY] * N + 0.5) else MODE_VENT


KIND = ControllerKind(settings=FixedDutySettings, code=CODE, law=law, firmware=None, tracks=None,
                      gains=(Gain("duty", "", 0.0, 1.0),))
'''

RUN = r'''
import json, subprocess, sys
import numpy as np
import frogsim
from frogsim.sweep import run_sweep
out = {}
# vent-always: a muscle at 3 bar gauge, vented from the first sample on
d = {"name": "vent", "duration": "1 s", "output_interval": "1 ms", "supply": {"mode": "none"},
     "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}, "initial_pressure_gauge": "3 bar"}},
     "controllers": {"vent": {"kind": "vent-always", "muscle": "hip"}}}
r = frogsim.simulate(frogsim.load_scenario(d))
out["vent"] = {"t": r.t.tolist(), "charge": r.u[:, 0].tolist(), "discharge": r.u[:, 1].tolist(),
               "p": r.muscle_pressure("hip").tolist(), "p_exhaust": r.exhaust_pressure.tolist(),
               "patm": r.atmospheric_pressure, "dead": r.model.scenario.valves.discharge.dead_time,
               "switchings": list(r.switchings["hip"]), "metrics": r.control_metrics()["vent"]}
# fixed-duty: no dead time, the charge valve open 3 of every 10 samples
d = {"name": "fixed", "duration": "0.5 s", "output_interval": "1 ms", "supply": {"mode": "none"},
     "valves": {"charge": {"dead_time": "0 ms"}, "discharge": {"dead_time": "0 ms"}},
     "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
     "controllers": {"loop": {"kind": "fixed-duty", "muscle": "hip", "duty": 0.3, "period_samples": 10}}}
r = frogsim.simulate(frogsim.load_scenario(d))
out["charge_fraction"] = float(r.u[:-1, 0].mean())
out["vent_and_charge_together"] = bool((r.u[:, 0] * r.u[:, 1]).any())
out["switchings"] = list(r.switchings["hip"])
with open("one-hip.toml", "w") as f:
    f.write('name = "fixed"\nduration = "0.5 s"\noutput_interval = "1 ms"\n[supply]\nmode = "none"\n'
            '[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
            '[controllers.loop]\nkind = "fixed-duty"\nmuscle = "hip"\nduty = 0.3\n')
spec = {"name": "fixed-sweep", "base": {"scenario": "one-hip.toml"},
        "sweep": {"method": "grid", "parameters": {"controllers.loop.duty": [0.2, 0.6]}},
        "record": {"metrics": ["air_used"], "muscle": "hip"}}
ds = run_sweep(spec, progress=False, workers=1)
out["sweep"] = [float(x) for x in ds["air_used"].values]
single = []
for v in (0.2, 0.6):
    r = frogsim.simulate(frogsim.load_scenario("one-hip.toml").replace({"controllers.loop.duty": v}))
    single.append(float((r.charged_mass("hip")[-1] - r.charged_mass("hip")[0]) / r.reference_density))
out["single"] = single
# frogsim firmware on a vent-always scenario: refused, nothing written
with open("vent.toml", "w") as f:
    f.write('name = "vent"\nduration = "1 s"\n[supply]\nmode = "none"\n'
            '[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
            '[controllers.vent]\nkind = "vent-always"\nmuscle = "hip"\n[firmware]\n')
fw = subprocess.run([sys.executable, "-m", "frogsim", "firmware", "vent.toml", "--out", "fw"],
                    capture_output=True, text=True)
out["firmware"] = {"code": fw.returncode, "stderr": fw.stderr}
print(json.dumps(out))
'''
