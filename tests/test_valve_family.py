"""The valve family: valve types one module each, found through their registry; the switching valve
its first member (the same numbers as Eq. (8) written out); the proportional valve's physics (spool
edge conductance, its first-order lag, C from the catalogue's nominal flow) and its plant; the PID
kind that drives it, refused on switching valves and by `frogsim firmware`; and a new valve type
is one new module, nothing else edited."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import frogsim
from frogsim.errors import ScenarioError
from tests.conftest import P_ATM
from tests.test_control import closed_loop
from tests.package_copy import package_copy, run_copy as _run_copy

BAR = 1e5
L_PER_MIN = 1e-3 / 60.0
RHO_REF = 1e5 / (287.0 * 293.15)          # ISO 8778 reference density (the parameter set's air)
T_REF = 293.15


def _proportional(controller: dict | None = None, duration: float = 0.3, **extra) -> dict:
    extra = {"supply": {"mode": "none"}, "valves": {"type": "proportional"}, **extra}
    return closed_loop(controller or {"kind": "pid", "setpoint": "3 bar"}, duration, **extra)


# --- the registry ----------------------------------------------------------------------------------------
def test_the_registry_holds_the_shipped_types_with_unique_codes():
    from frogsim.circuit import valves
    from frogsim.scenario import valves as loader
    assert {"switching", "proportional"} <= set(valves.TYPES)
    codes = [v.code for v in valves.TYPES.values()]
    assert len(codes) == len(set(codes))
    assert all(loader.TYPES[name] is v.settings for name, v in valves.TYPES.items())
    assert valves.TYPES["proportional"].continuous and not valves.TYPES["switching"].continuous


def test_an_unknown_valve_type_is_refused_naming_the_field_and_the_types():
    with pytest.raises(ScenarioError, match=r"valves\.type = 'piezo': must be one of 'proportional', 'switching'|"
                                            r"valves\.type = 'piezo': must be one of 'switching', 'proportional'"):
        frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar"}, valves={"type": "piezo"}))


BASE_TOML = ('name = "v"\nduration = "0.1 s"\n[supply]\nmode = "none"\n'
             '[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
             '[controllers.loop]\nkind = "bang-bang"\nmuscle = "hip"\nsetpoint = "3 bar"\n')


@pytest.mark.parametrize("valves, field", [
    ('[valves]\ntype = "piezo"\n', "valves.type = 'piezo'"),
    ('[valves]\ntype = "proportional"\nbandwidth = "-5 Hz"\n', "valves.bandwidth"),
    ('[valves]\ntype = "proportional"\nnominal_flow = "700"\n', "valves.nominal_flow"),
    ('[valves]\ntype = "proportional"\nsignal_span = "6 V"\n', "valves.signal_span = 6 V"),
])
def test_a_bad_valve_setting_exits_2_in_one_line_writing_nothing(tmp_path, capsys, valves, field):
    from frogsim.cli import main
    path = tmp_path / "bad.toml"
    path.write_text(BASE_TOML + valves)
    out = tmp_path / "out"
    code = main(["simulate", str(path), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert field in err, err
    assert not out.exists()


def test_a_scenario_naming_another_type_drops_the_parameter_sets_valves():
    """fan2017's [valves.charge] and [valves.discharge] are the switching valve's: a scenario of type
    proportional loads without them (no unknown-key error) and with the catalogue's defaults."""
    sc = frogsim.load_scenario(_proportional())
    assert sc.valves.type == "proportional"
    assert sc.valves.nominal_flow == pytest.approx(700 * L_PER_MIN)
    with pytest.raises(ScenarioError, match=r"valves\.charge"):
        frogsim.load_scenario(_proportional(valves={"type": "proportional", "charge": {"dead_time": "1 ms"}}))


def test_a_muscle_row_carries_its_valve_code_and_block():
    from frogsim.circuit import layout as L
    from frogsim.circuit.valves import proportional, switching
    m = frogsim.build_model(frogsim.load_scenario("paper-cycle"))
    assert np.all(m.mp[:, L.M_VALVE] == switching.CODE)
    assert m.mp[:, L.M_VP + switching.P_CC] == pytest.approx([0.4e-3 / BAR] * 6, rel=1e-15)
    assert np.all(m.mp[:, L.M_VP + switching.P_DB] == 0.38)
    p = frogsim.build_model(frogsim.load_scenario(_proportional()))
    assert p.mp[0, L.M_VALVE] == proportional.CODE
    assert p.mp[0, L.M_VP + proportional.P_TAU] == pytest.approx(1.0 / (2 * math.pi * 100.0), rel=1e-15)


def test_the_switching_flows_are_eq8_written_out_bit_for_bit():
    """The family's flows of a switching valve are the numbers of Eq. (8) called directly (what the
    right-hand side computed before the family), open paths only."""
    from frogsim.circuit import layout as L
    from frogsim.circuit.valves import BY_CODE
    from frogsim.physics.flow import iso6358_mass_flow
    m = frogsim.build_model(frogsim.load_scenario("paper-cycle"))
    mp = m.mp
    C, b, mi, rl = mp[0, L.M_VP:L.M_VP + 4]            # the parameter set's MHJ9: 0.4 L/(s bar), 0.38, 0.5, 0.999
    assert (C * 1e8, b, mi, rl) == pytest.approx((0.4, 0.38, 0.5, 0.999), rel=1e-14)
    rng = np.random.default_rng(3)
    for _ in range(50):
        p_s, p_i, p_e = rng.uniform(0.9e5, 8e5, 3)
        T_s, T_i, T_e = rng.uniform(250, 330, 3)
        u_c, u_d = rng.integers(0, 2, 2).astype(float)
        mc, md = BY_CODE[mp[0, L.M_VALVE]].flows(mp, 0, u_c, u_d, p_s, T_s, p_i, T_i, p_e, T_e, RHO_REF, T_REF)
        want_c = iso6358_mass_flow(p_s, T_s, p_i, T_i, C, b, mi, rl, RHO_REF, T_REF) if u_c else 0.0
        want_d = iso6358_mass_flow(p_i, T_i, p_e, T_e, C, b, mi, rl, RHO_REF, T_REF) if u_d else 0.0
        assert (mc, md) == (want_c, want_d)


def test_an_unknown_valve_code_stops_the_run():
    from frogsim.circuit import layout as L
    m = frogsim.build_model(frogsim.load_scenario(closed_loop({"kind": "bang-bang", "setpoint": "3 bar"}, 0.05)))
    m.mp[0, L.M_VALVE] = 9.0
    with pytest.raises(Exception, match="valve code is no valve type's"):
        frogsim.simulate(m)


# --- the proportional valve's physics ----------------------------------------------------------------------
def test_spool_edge_conductance():
    from frogsim.physics.flow import spool_conductance
    C = 2.8e-8
    assert spool_conductance(0.25, C, 0.0, 0.0) == pytest.approx(0.7e-8)
    assert spool_conductance(0.0, C, 0.0, 0.0) == 0.0
    assert spool_conductance(1.0, C, 0.1, 1e-10) == C
    assert spool_conductance(0.1, C, 0.1, 1e-10) == 1e-10           # shut at the overlap's end: the leakage
    assert spool_conductance(0.55, C, 0.1, 0.0) == pytest.approx(0.5 * C)


def test_the_nominal_flow_gives_back_its_conductance():
    """C from 700 L/min at 7.013 -> 6.013 bar abs, put back into Eq. (8) at those pressures (T_ref),
    passes 700 L/min; the worked number of the docstring (b = 0.3: 2.75 L/(s bar))."""
    from frogsim.physics.flow import iso6358_mass_flow, sonic_conductance_from_nominal_flow
    p1 = 101325.0 + 6e5
    C = sonic_conductance_from_nominal_flow(700 * L_PER_MIN, p1, p1 - 1e5, 0.3)
    sigma = (p1 - 1e5) / p1
    assert C == pytest.approx(700 * L_PER_MIN / (p1 * math.sqrt(1 - ((sigma - 0.3) / 0.7) ** 2)), rel=1e-12)
    assert C * 1e8 == pytest.approx(2.75, abs=0.005)
    q = iso6358_mass_flow(p1, T_REF, p1 - 1e5, T_REF, C, 0.3, 0.5, 1.0, RHO_REF, T_REF) / RHO_REF
    assert q == pytest.approx(700 * L_PER_MIN, rel=1e-12)


def test_the_spool_lag_is_the_first_order_solution():
    """Over one period from x0 under a held command xc: the end is xc + (x0 - xc) e^(-dt/tau) and
    the mean the integral of that path over the period (compared with a fine trapezoidal sum)."""
    from frogsim.physics.flow import spool_lag
    tau, dt = 1.0 / (2 * math.pi * 100.0), 1e-3
    for x0, xc in ((0.0, 1.0), (0.7, -0.4), (-1.0, -1.0)):
        end, mean = spool_lag(x0, xc, dt, tau)
        s = np.linspace(0.0, dt, 20001)
        path = xc + (x0 - xc) * np.exp(-s / tau)
        assert end == pytest.approx(path[-1], rel=1e-12, abs=1e-15)
        assert mean == pytest.approx(np.trapezoid(path, s) / dt, rel=1e-7, abs=1e-12)
    assert spool_lag(0.2, 0.9, dt, 0.0) == (0.9, 0.9)              # no lag: the spool follows at once


def test_the_controllers_view_of_the_spool_follows_the_lag_sample_by_sample():
    """A held command +1 from the mid position: after k samples the spool is at 1 - e^(-k dt/tau),
    and the openings written each period are that period's mean (charge edge only)."""
    from frogsim.circuit import layout as L
    from frogsim.circuit.valves import BY_CODE
    m = frogsim.build_model(frogsim.load_scenario(_proportional()))
    tau, dt = 1.0 / (2 * math.pi * 100.0), 1e-3
    x = 0.0
    for k in range(1, 8):
        u_c, u_d, x_next = BY_CODE[m.mp[0, L.M_VALVE]].openings(m.mp, 0, 1.0, x, dt)
        assert x_next == pytest.approx(1.0 - math.exp(-k * dt / tau), rel=1e-12)
        assert u_c == pytest.approx(1.0 - (tau / dt) * (math.exp(-(k - 1) * dt / tau) - math.exp(-k * dt / tau)),
                                    rel=1e-12)
        assert u_d == 0.0
        x = x_next
    u_c, u_d, _ = BY_CODE[m.mp[0, L.M_VALVE]].openings(m.mp, 0, -3.0, 0.0, dt)     # clipped to -1: vent edge
    assert u_c == 0.0 and 0.0 < u_d < 1.0


def test_a_fully_open_proportional_valve_charges_at_its_choked_flow():
    """An open-loop program "charge" opens the charge edge fully at once: the first millisecond's
    mass flow is Eq. (8) choked from the source, C p_s rho_ref sqrt(T_ref / T_s), with C from the
    catalogue's 700 L/min (about 6.9 times the MHJ9's 0.4 L/(s bar))."""
    d = {"name": "open", "duration": "0.05 s", "output_interval": "0.1 ms", "supply": {"mode": "none"},
         "valves": {"type": "proportional"}, "programs": {"up": {"pressurise": "1 s", "release": "1 s"}},
         "muscles": {"hip": {"type": "hip", "program": "up", "motion": {"kind": "constant"}}}}
    r = frogsim.simulate(frogsim.load_scenario(d))
    C = r.model.scenario.valves.sonic_conductance
    assert C / 0.4e-8 == pytest.approx(6.9, abs=0.05)
    p_s = P_ATM + 6 * BAR
    i1 = int(np.searchsorted(r.t, 0.5e-3 - 1e-12))
    slope = r.charged_mass("hip")[i1] / r.t[i1]
    # choked (p_i / p_s < b) over that half millisecond; the source falls by well under 0.1 %
    assert slope == pytest.approx(C * RHO_REF * p_s, rel=2e-3)
    assert r.muscle_pressure("hip")[-1] == pytest.approx(r.source_pressure[-1], rel=2e-3)


# --- the PID kind --------------------------------------------------------------------------------------------
def test_pid_tracks_a_step_on_the_proportional_valve_and_never_opens_both_edges():
    r = frogsim.simulate(frogsim.load_scenario(_proportional({"kind": "pid", "setpoint": "3 bar",
                                                               "settle": "0.1 s"}, 0.3)))
    p = (r.muscle_pressure("hip") - P_ATM) / BAR
    assert abs(p[-1] - 3.0) < 0.01
    assert not np.any(r.u[:, 0] * r.u[:, 1])
    assert np.all((r.u >= 0.0) & (r.u <= 1.0))
    assert 0.0 < r.u[:, 0].max() <= 1.0
    assert r.control_metrics()["loop"]["tracking_error_rms_bar"] < 0.01


def test_air_is_conserved_through_the_spool_and_its_counters_balance():
    """A 1 Hz sine tracked through the proportional valve (charge and vent edges in turn, with a
    leakage so that both edges pass air at once): the circuit's air stays constant to rounding, and
    the muscle's mass changes by what its counters say entered minus what left."""
    r = frogsim.simulate(frogsim.load_scenario(_proportional(
        {"kind": "pid", "setpoint": {"kind": "sine", "mean": "3 bar", "amplitude": "2 bar", "frequency": "1 Hz"}},
        1.0, valves={"type": "proportional", "leakage_conductance": "0.01 L/(s*bar)"})))
    m = r.total_air_mass
    assert np.max(np.abs(m - m[0])) < 1e-12 * m[0] * 1e3
    i = r.model.names.index("hip")
    from frogsim.circuit import layout as L
    own = r.y[:, L.mass_index(i)]
    np.testing.assert_allclose(own - own[0], r.charged_mass("hip") - r.vented_mass("hip"), rtol=0, atol=1e-9 * own[0])
    assert r.vented_mass("hip")[-1] > 0.0 and r.charged_mass("hip")[-1] > 0.0


def test_pid_on_switching_valves_is_refused_naming_the_controller():
    with pytest.raises(ScenarioError, match=r"controllers\.loop\.kind = 'pid': commands a proportional valve's "
                                            r"spool, but valves\.type is 'switching'"):
        frogsim.load_scenario(closed_loop({"kind": "pid", "setpoint": "3 bar"}))


def test_pid_gains_are_read_in_volts_per_bar():
    sc = frogsim.load_scenario(_proportional({"kind": "pid", "setpoint": "3 bar", "proportional_gain": "2 V/bar",
                                              "integral_gain": "50 V/(bar*s)", "derivative_gain": "0.01 V*s/bar"}))
    c = sc.controllers["loop"]
    assert (c.proportional_gain, c.integral_gain, c.derivative_gain) == pytest.approx((2e-5, 5e-4, 1e-7))
    with pytest.raises(ScenarioError, match=r"controllers\.loop\.proportional_gain"):
        frogsim.load_scenario(_proportional({"kind": "pid", "setpoint": "3 bar", "proportional_gain": "2 bar"}))


def test_firmware_refuses_the_pid_kind_in_one_line(tmp_path, capsys):
    from frogsim.cli import main
    path = tmp_path / "pid.toml"
    path.write_text('name = "pid"\nduration = "0.2 s"\n[supply]\nmode = "none"\n[valves]\ntype = "proportional"\n'
                    '[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
                    '[controllers.loop]\nkind = "pid"\nmuscle = "hip"\nsetpoint = "3 bar"\n[firmware]\n')
    out = tmp_path / "fw"
    code = main(["firmware", str(path), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert "controllers.loop.kind = 'pid'" in err and "no firmware twin" in err, err
    assert not out.exists()


# --- a new valve type is one new module -----------------------------------------------------------------
VALVE_MODULE = '''
"""Valve type "throttled": a throw-away type (tests): one on/off valve per path, one conductance."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from frogsim._jit import jit
from frogsim.circuit.layout import M_VP
from frogsim.circuit.valves.spec import ValveType
from frogsim.physics.flow import iso6358_mass_flow
from frogsim.scenario.fields import quantity
from frogsim.scenario.schema import Valve
from frogsim.scenario.valves import ValveSettings

CODE = {code!r}


@dataclass(frozen=True)
class ThrottledValve(ValveSettings):
    TYPE: ClassVar[str] = "throttled"
    sonic_conductance: float = quantity("conductance", gt=0.0, display="L/(s*bar)", default=0.2e-8)
    critical_ratio: float = quantity("dimensionless", ge=0.0, lt=1.0, default=0.4)

    @property
    def charge(self):
        return Valve(sonic_conductance=self.sonic_conductance, critical_ratio=self.critical_ratio,
                     laminar_ratio=0.999, dead_time=0.0)

    @property
    def discharge(self):
        return self.charge


def block(v):
    return (v.sonic_conductance, v.critical_ratio)


@jit
def flows(mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref):
    mc = 0.0
    md = 0.0
    if u_c > 0.5:
        mc = iso6358_mass_flow(p_up, T_up, p_i, T_i, mp[i, M_VP], mp[i, M_VP + 1], 0.5, 0.999, rho_ref, T_ref)
    if u_d > 0.5:
        md = iso6358_mass_flow(p_i, T_i, p_e, T_e, mp[i, M_VP], mp[i, M_VP + 1], 0.5, 0.999, rho_ref, T_ref)
    return mc, md


@jit
def openings(mp, i, command, memory, dt):
    return (1.0 if command > 0 else 0.0), (1.0 if command < 0 else 0.0), memory


VALVE = ValveType(settings=ThrottledValve, code=CODE, block=block, flows=flows, openings=openings)
'''

VALVE_RUN = r'''
import json
import frogsim
out = {}
d = {"name": "open", "duration": "0.05 s", "output_interval": "0.1 ms", "supply": {"mode": "none"},
     "valves": {"type": "throttled", "sonic_conductance": "0.2 L/(s*bar)"},
     "programs": {"up": {"pressurise": "1 s", "release": "1 s"}},
     "muscles": {"hip": {"type": "hip", "program": "up", "motion": {"kind": "constant"}}}}
r = frogsim.simulate(frogsim.load_scenario(d))
out["t"] = r.t.tolist()
out["q"] = r.charged_mass("hip").tolist()
out["rho"] = r.reference_density
out["p_s"] = float(r.source_pressure[0])
# a controller driving it (its view: a mode's sign), no dead time
d = {"name": "loop", "duration": "0.3 s", "output_interval": "1 ms", "supply": {"mode": "none"},
     "valves": {"type": "throttled"},
     "muscles": {"hip": {"type": "hip", "motion": {"kind": "constant"}}},
     "controllers": {"loop": {"kind": "bang-bang", "muscle": "hip", "setpoint": "3 bar", "band": "0.1 bar",
                              "settle": "0.2 s"}}}
r = frogsim.simulate(frogsim.load_scenario(d))
out["p_end"] = float(r.muscle_pressure("hip")[-1] - r.atmospheric_pressure)
out["rms"] = r.control_metrics()["loop"]["tracking_error_rms_bar"]
print(json.dumps(out))
'''


def _valve_copy(root, modules: dict):
    """A copy of the package under root/src with ``modules`` ({file name: text}) added to
    circuit/valves/ (:func:`tests.package_copy.package_copy`). Returns root/src."""
    return package_copy(root, {f"circuit/valves/{name}": text for name, text in modules.items()})


def test_a_duplicate_valve_code_is_refused_naming_both_modules(tmp_path):
    src = _valve_copy(tmp_path, {"a_throttled.py": VALVE_MODULE.format(code=1.0)})
    done = _run_copy(src, "-c", "import frogsim", cwd=tmp_path)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: valve types: "), done.stderr[-2000:]
    assert "CODE 1.0 of frogsim.circuit.valves.switching (type 'switching') is already taken by " \
           "frogsim.circuit.valves.a_throttled (type 'throttled')" in last, last
