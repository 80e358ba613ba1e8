"""Controller kinds: one module each, found through the registry; their settings checked like any
other field (units by dimension, ranges that make physical sense); a Python law's metrics carry
its own label and setpoint; a new kind is one module plus its dispatch entry."""
from __future__ import annotations

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
from tests.test_control import closed_loop

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "frogsim"
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


# --- adding a kind ------------------------------------------------------------------------------------
FIXED_DUTY = '''
"""Kind "fixed-duty": a throw-away law (tests): charge for the first round(duty N) samples of each
period of N samples, vent for the rest."""
from __future__ import annotations

import math
from dataclasses import dataclass

from frogsim._jit import jit
from frogsim.control.kinds.common import SensedLoop
from frogsim.control.signals import B_PHASE, MODE_CHARGE, MODE_VENT
from frogsim.control.table import L_DUTY, L_PERIOD_N, valve_row
from frogsim.scenario.fields import integer, quantity
from frogsim.scenario.kinds import register

CODE = 9.0


@register
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
def law(laws, c, cs, b, y, p, ts):
    N = int(laws[c, L_PERIOD_N])
    phase = int(cs[b + B_PHASE])
    cs[b + B_PHASE] = float((phase + 1) % N)
    return MODE_CHARGE if phase < math.floor(laws[c, L_DUTY] * N + 0.5) else MODE_VENT
'''

DISPATCH_ANCHOR = "        elif kind == joint_angle.CODE:\n            mode = joint_angle.law(laws, c, cs, b, y, p, ts)\n"

RUN = '''
import json, sys
import numpy as np
import frogsim
from frogsim.sweep import run_sweep
d = {"name": "fixed", "duration": "0.5 s", "output_interval": "1 ms", "supply": {"mode": "none"},
     "valves": {"charge": {"dead_time": "0 ms"}, "discharge": {"dead_time": "0 ms"}},
     "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
     "controllers": {"loop": {"kind": "fixed-duty", "muscle": "hip", "duty": 0.3, "period_samples": 10}}}
sc = frogsim.load_scenario(d)
r = frogsim.simulate(sc)
charge = r.u[:, 0]
out = {"charge_fraction": float(charge[:-1].mean()), "vent_and_charge_together": bool((r.u[:, 0] * r.u[:, 1]).any()),
       "switchings": r.switchings["hip"]}
with open("one-hip.toml", "w") as f:
    f.write("""name = "fixed"
duration = "0.5 s"
output_interval = "1 ms"
[supply]
mode = "none"
[muscles.hip]
type = "hip"
motion = { kind = "constant" }
[controllers.loop]
kind = "fixed-duty"
muscle = "hip"
duty = 0.3
""")
spec = {"name": "fixed-sweep", "base": {"scenario": "one-hip.toml"},
        "sweep": {"method": "grid", "parameters": {"controllers.loop.duty": [0.2, 0.6]}},
        "record": {"metrics": ["air_used"], "muscle": "hip"}}
ds = run_sweep(spec, progress=False, workers=1)
pts = [float(x) for x in ds["air_used"].values]
single = []
for v in (0.2, 0.6):
    r = frogsim.simulate(frogsim.load_scenario("one-hip.toml").replace({"controllers.loop.duty": v}))
    single.append(float((r.charged_mass("hip")[-1] - r.charged_mass("hip")[0]) / r.reference_density))
out["sweep"] = pts
out["single"] = single
print(json.dumps(out))
'''


@pytest.mark.slow          # compiles the engine afresh in the copy (about a minute)
def test_a_new_kind_is_one_module_and_its_dispatch_entry(tmp_path):
    """In a copy of the package, a fixed-duty kind added as one new module plus its entry in the
    compiled dispatch (an import and one branch of sample_controllers) runs in simulate and in a
    sweep; the charge valve is open the duty's fraction of the time."""
    pkg = tmp_path / "src" / "frogsim"
    shutil.copytree(PACKAGE, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (pkg / "control" / "kinds" / "fixed_duty.py").write_text(FIXED_DUTY)
    sampled = pkg / "control" / "sampled.py"
    text = sampled.read_text()
    assert DISPATCH_ANCHOR in text
    text = text.replace("from frogsim.control.kinds import bang_bang, joint_angle, pwm, sliding_mode",
                        "from frogsim.control.kinds import bang_bang, fixed_duty, joint_angle, pwm, sliding_mode")
    text = text.replace(DISPATCH_ANCHOR, DISPATCH_ANCHOR + "        elif kind == fixed_duty.CODE:\n"
                                                          "            mode = fixed_duty.law(laws, c, cs, b, y, p, ts)\n")
    sampled.write_text(text)
    work = tmp_path / "run"
    work.mkdir()
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "src"), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    done = subprocess.run([sys.executable, "-c", RUN], cwd=work, env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    # no dead time: the charge valve is open 3 of every 10 samples (1 ms each), vent the other 7
    assert out["charge_fraction"] == pytest.approx(0.3, abs=0.01)
    assert not out["vent_and_charge_together"]
    assert abs(out["switchings"][0] - 2 * 50) <= 1      # 50 periods of 10 ms: it opens and closes once in each
    # the sweep's points are the single runs (air charged over the run, a standard volume [m^3])
    np.testing.assert_allclose(out["sweep"], out["single"], rtol=1e-12)
    assert out["sweep"][1] > out["sweep"][0] > 0.0     # more duty, more air
