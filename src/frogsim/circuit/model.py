"""Build the flat-array model the engine integrates, once, from a validated Scenario."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frogsim.circuit import layout as L
from frogsim.components.schema import VALVE_STATES, Scenario
from frogsim.errors import ScenarioError
from frogsim.physics.air import critical_pressure_ratio
from frogsim.physics.flow import main_pipe_branch_limit, tube_sonic_conductance
from frogsim.physics.muscle import braid_parameters, crank_muscle_length, muscle_volume


@dataclass(frozen=True)
class MotionKnots:
    """Cubic Hermite knots of one muscle's length: times [s], lengths [m], slopes [m/s]."""
    t: np.ndarray
    L: np.ndarray
    dL: np.ndarray
    fixed_volume: float = 0.0   # > 0: the total volume is held at this value [m^3]


def command_time(t: float, rate: float) -> float:
    """The first controller sample at or after t [s] (commands are issued at samples)."""
    return math.ceil(t * rate - 1e-9) / rate


def _stroke_knots(mname, m, mt, L0, rate, duration):
    eps = mt.stroke_contraction if m.motion.contraction is None else m.motion.contraction
    L_c = L0 * (1.0 - eps)
    ts, Ls = [0.0], [L0]
    current = L0
    for t_cmd, state in m.program.steps:
        if state == "hold":
            continue
        target = L_c if state == "charge" else L0
        if target == current:
            continue
        dur = m.motion.rise if state == "charge" else m.motion.fall
        t0 = command_time(t_cmd, rate) + m.motion.delay
        if t0 <= ts[-1]:
            key = "fall" if state == "charge" else "rise"
            raise ScenarioError(f"muscles.{mname}.motion.{key}", f"{getattr(m.motion, key):g} s",
                                f"the previous stroke must end before the next command moves the "
                                f"muscle (at {t_cmd:g} s + delay)")
        ts += [t0, t0 + dur]
        Ls += [current, target]
        current = target
    t = np.array(ts)
    return MotionKnots(t, np.array(Ls), np.zeros_like(t))


def _pchip_knots(t, Lv):
    from scipy.interpolate import PchipInterpolator
    t = np.asarray(t, float)
    Lv = np.asarray(Lv, float)
    if t.size == 1:
        return MotionKnots(t, Lv, np.zeros(1))
    slopes = PchipInterpolator(t, Lv).derivative()(t)
    return MotionKnots(t, Lv, slopes)


def _joint_knots(mname, m, mt, L0, base_dir):
    import pandas as pd
    path = Path(base_dir) / m.motion.file
    where = f"muscles.{mname}.motion.file"
    if not path.exists():
        raise ScenarioError(where, m.motion.file, "file not found")
    try:
        df = pd.read_csv(path)
    except Exception as exc:  # pandas raises many parser errors
        raise ScenarioError(where, m.motion.file, f"not a readable CSV ({exc})") from None
    for key in (m.motion.time_column, m.motion.column):
        if key not in df.columns:
            raise ScenarioError(f"muscles.{mname}.motion.column", key,
                                f"must be a column of {path.name} ({', '.join(df.columns)})")
    t = df[m.motion.time_column].to_numpy(float)
    ang = np.radians(df[m.motion.column].to_numpy(float))
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(ang))) or np.any(np.diff(t) <= 0):
        raise ScenarioError(where, m.motion.file, "times must be finite and increasing, angles finite")
    Lv = np.array([crank_muscle_length(a, mt.anchor_distance, mt.crank_radius, mt.rest_angle, L0,
                                       float(mt.side)) for a in ang])
    contraction = 1.0 - Lv / L0
    worst = float(contraction.max())
    if worst > mt.max_contraction:
        raise ScenarioError(where, m.motion.file,
                            f"joint angles contract the muscle by {worst:.1%}, beyond its "
                            f"max_contraction ({mt.max_contraction:.0%})")
    if float(contraction.min()) < -1e-9:
        raise ScenarioError(where, m.motion.file,
                            f"joint angles stretch the muscle {-contraction.min():.1%} beyond its rest "
                            "length; the crank geometry (rest_angle, side) may not match the data")
    return _pchip_knots(t, Lv)


def build_motions(scenario: Scenario) -> dict[str, MotionKnots]:
    """Length knots (or a fixed volume) for every muscle; raises ScenarioError on bad motions."""
    out = {}
    rate = scenario.controller.rate
    for mname, m in scenario.muscles.items():
        mt = scenario.muscle_types[m.type]
        L0 = mt.nominal_length
        kind = m.motion.kind
        if kind == "stroke":
            knots = _stroke_knots(mname, m, mt, L0, rate, scenario.duration)
        elif kind == "constant":
            eps = m.motion.contraction or 0.0
            knots = MotionKnots(np.zeros(1), np.array([L0 * (1.0 - eps)]), np.zeros(1))
        elif kind == "volume_constant":
            eps = mt.stroke_contraction if m.motion.contraction is None else m.motion.contraction
            b0, n = braid_parameters(L0, mt.inner_diameter, mt.braid_angle)
            v_rest = muscle_volume(L0, b0, n)
            v_max = max(muscle_volume(L0 * (1.0 - e), b0, n) for e in np.linspace(0.0, eps, 201))
            v = v_rest + m.motion.fraction * (v_max - v_rest) + mt.dead_volume
            knots = MotionKnots(np.zeros(1), np.array([L0]), np.zeros(1), fixed_volume=v)
        elif kind == "table":
            Lv = L0 * (1.0 - np.asarray(m.motion.contraction_percent) / 100.0)
            knots = _pchip_knots(m.motion.time_s, Lv)
        else:
            knots = _joint_knots(mname, m, mt, L0, scenario.base_dir)
        out[mname] = knots
    return out


def build_schedule(scenario: Scenario):
    """Valve switching times and states: commands at controller samples, plus each valve's dead time.

    Returns (sched_t (S,), sched_u (S, 2n), u0 (2n,), charge_open_times: list of arrays per muscle).
    """
    rate = scenario.controller.rate
    v = scenario.valves
    events = []
    opens = []
    names = list(scenario.muscles)
    for i, name in enumerate(names):
        m = scenario.muscles[name]
        ch_open = []
        prev = (0, 0)
        for t_cmd, state in m.program.steps:
            tq = command_time(t_cmd, rate)
            new = VALVE_STATES[state]
            if new[0] != prev[0]:
                events.append((tq + v.charge.dead_time, 2 * i, float(new[0])))
                if new[0]:
                    ch_open.append(tq + v.charge.dead_time)
            if new[1] != prev[1]:
                events.append((tq + v.discharge.dead_time, 2 * i + 1, float(new[1])))
            prev = new
        opens.append(np.array(ch_open))
    events.sort()
    u = np.zeros(2 * len(names))
    times, states = [], []
    for t, j, val in events:
        u[j] = val
        if times and abs(times[-1] - t) < 1e-12:
            states[-1] = u.copy()
        else:
            times.append(t)
            states.append(u.copy())
    sched_u = np.array(states) if states else np.zeros((0, 2 * len(names)))
    return np.array(times, float), sched_u.reshape(len(times), 2 * len(names)), np.zeros(2 * len(names)), opens


def add_breakpoints(sched_t, sched_u, u0, times):
    """Merge extra stop times into a schedule, carrying the valve states in force at each.

    The prescribed motion's knots are kinks in dV/dt; stopping there keeps every step smooth.
    """
    times = np.asarray(times, float)
    new = np.setdiff1d(times, sched_t)
    if new.size == 0:
        return sched_t, sched_u
    all_t = np.concatenate([sched_t, new])
    order = np.argsort(all_t, kind="stable")
    states = np.empty((all_t.size, u0.size))
    for k, t in enumerate(all_t):
        idx = np.searchsorted(sched_t, t, side="right") - 1
        states[k] = sched_u[idx] if idx >= 0 else u0
    return all_t[order], states[order]


def branch_limit_standard(scenario: Scenario) -> float:
    """Paper-mode per-branch limit as a standard volume flow [m^3/s]: the override or Eq. (9)."""
    s = scenario.supply
    if s.branch_limit is not None:
        return s.branch_limit
    return main_pipe_branch_limit(s.main_tube_inner_diameter, s.velocity_limit, s.main_tube_count,
                                  s.branch_count)


@dataclass
class PneumaticModel:
    """Flat arrays for the engine (see :mod:`frogsim.circuit.layout`) built from one Scenario."""
    scenario: Scenario
    names: list
    g: np.ndarray
    mp: np.ndarray
    mot_t: np.ndarray
    mot_L: np.ndarray
    mot_d: np.ndarray
    mot_n: np.ndarray
    sched_t: np.ndarray
    sched_u: np.ndarray
    u0: np.ndarray
    charge_open_times: list
    y0: np.ndarray
    atol: np.ndarray
    out_t: np.ndarray

    @property
    def n(self) -> int:
        return len(self.names)


def output_times(duration: float, interval: float) -> np.ndarray:
    """Output grid 0, interval, ..., duration (the end always included)."""
    n = int(math.floor(duration / interval + 1e-9))
    t = np.arange(n + 1) * interval
    if duration - t[-1] > 1e-9 * max(1.0, duration):
        t = np.append(t, duration)
    return t


def build_model(scenario: Scenario) -> PneumaticModel:
    """Flatten a Scenario into the arrays the engine loops over."""
    air = scenario.air
    R, k = air.gas_constant, air.heat_capacity_ratio
    patm = air.atmospheric_pressure_abs
    rho_ref = air.reference_density
    T_amb = air.ambient_temperature
    g = np.zeros(L.G_SIZE)
    g[L.G_K] = k
    g[L.G_R] = R
    g[L.G_PATM] = patm
    g[L.G_RHOREF] = rho_ref
    g[L.G_TREF] = air.reference_temperature
    g[L.G_TAMB] = T_amb
    g[L.G_VS] = scenario.source.volume
    g[L.G_VE] = scenario.exhaust.volume
    pump = scenario.pump
    g[L.G_PUMP_ENABLED] = 1.0 if pump.enabled and pump.displacement > 0 else 0.0
    g[L.G_PUMP_DISP] = pump.displacement
    g[L.G_PUMP_RMAX] = pump.max_pressure_ratio
    g[L.G_PUMP_ON] = patm + pump.on_below_gauge
    g[L.G_PUMP_OFF] = patm + pump.off_above_gauge
    sup = scenario.supply
    g[L.G_SUPPLY_MODE] = {"none": L.SUPPLY_NONE, "paper": L.SUPPLY_PAPER,
                          "physical": L.SUPPLY_PHYSICAL}[sup.mode]
    g[L.G_BRANCH_LIMIT] = rho_ref * branch_limit_standard(scenario)
    g[L.G_TUBE_C] = sup.main_tube_count * tube_sonic_conductance(
        sup.main_tube_inner_diameter, sup.discharge_coefficient, R, k, rho_ref, air.reference_temperature)
    g[L.G_TUBE_B] = critical_pressure_ratio(k)
    g[L.G_TUBE_RLAM] = scenario.valves.charge.laminar_ratio

    names = list(scenario.muscles)
    n = len(names)
    motions = build_motions(scenario)
    K = max(mk.t.size for mk in motions.values())
    mot_t = np.zeros((n, K))
    mot_L = np.zeros((n, K))
    mot_d = np.zeros((n, K))
    mot_n = np.zeros(n, dtype=np.int64)
    mp = np.zeros((n, L.M_SIZE))
    vc, vd = scenario.valves.charge, scenario.valves.discharge
    y0 = np.zeros(L.state_size(n))
    atol_scale = np.zeros_like(y0)
    for i, name in enumerate(names):
        m = scenario.muscles[name]
        mt = scenario.muscle_types[m.type]
        b0, nt = braid_parameters(mt.nominal_length, mt.inner_diameter, mt.braid_angle)
        mk = motions[name]
        nk = mk.t.size
        mot_t[i, :nk], mot_L[i, :nk], mot_d[i, :nk] = mk.t, mk.L, mk.dL
        mot_t[i, nk:] = mk.t[-1]
        mot_L[i, nk:] = mk.L[-1]
        mot_n[i] = nk
        mp[i] = 0.0
        mp[i, L.M_B0], mp[i, L.M_N], mp[i, L.M_DEAD] = b0, nt, mt.dead_volume
        mp[i, L.M_FIXEDV] = mk.fixed_volume
        mp[i, L.M_CC], mp[i, L.M_CB], mp[i, L.M_CM], mp[i, L.M_CRL] = (
            vc.sonic_conductance, vc.critical_ratio, vc.subsonic_index, vc.laminar_ratio)
        mp[i, L.M_DC], mp[i, L.M_DB], mp[i, L.M_DM], mp[i, L.M_DRL] = (
            vd.sonic_conductance, vd.critical_ratio, vd.subsonic_index, vd.laminar_ratio)
        mp[i, L.M_L0] = mt.nominal_length
        V0 = mk.fixed_volume if mk.fixed_volume > 0 else muscle_volume(mk.L[0], b0, nt) + mt.dead_volume
        p0 = patm + (m.initial_pressure_gauge if m.initial_pressure_gauge is not None
                     else scenario.exhaust.initial_pressure_gauge)
        j = L.Y_MUSCLE0 + 2 * i
        y0[j] = p0 * V0 / (R * T_amb)
        y0[j + 1] = p0
        scale_m = patm * V0 / (R * T_amb)
        atol_scale[j] = scale_m
        atol_scale[j + 1] = patm
        atol_scale[L.charged_index(i, n)] = scale_m
        atol_scale[L.vented_index(i, n)] = scale_m
    ps0 = patm + scenario.source.initial_pressure_gauge
    pe0 = patm + scenario.exhaust.initial_pressure_gauge
    y0[L.Y_MS] = ps0 * scenario.source.volume / (R * T_amb)
    y0[L.Y_PS] = ps0
    y0[L.Y_ME] = pe0 * scenario.exhaust.volume / (R * T_amb)
    y0[L.Y_PE] = pe0
    atol_scale[L.Y_MS] = patm * scenario.source.volume / (R * T_amb)
    atol_scale[L.Y_PS] = patm
    atol_scale[L.Y_ME] = patm * scenario.exhaust.volume / (R * T_amb)
    atol_scale[L.Y_PE] = patm
    atol_scale[L.pump_index(n)] = atol_scale[L.Y_MS]
    sched_t, sched_u, u0, opens = build_schedule(scenario)
    knots = np.unique(np.concatenate([mk.t for mk in motions.values() if mk.fixed_volume <= 0]
                                     + [np.zeros(0)]))
    sched_t, sched_u = add_breakpoints(sched_t, sched_u, u0, knots[knots > 0])
    return PneumaticModel(scenario=scenario, names=names, g=g, mp=mp, mot_t=mot_t, mot_L=mot_L,
                          mot_d=mot_d, mot_n=mot_n, sched_t=sched_t, sched_u=sched_u, u0=u0,
                          charge_open_times=opens, y0=y0, atol=scenario.solver.rtol * atol_scale,
                          out_t=output_times(scenario.duration, scenario.output_interval))
