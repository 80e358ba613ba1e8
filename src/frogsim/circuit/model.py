"""Build the flat-array model the engine integrates, once, from a validated Scenario."""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from frogsim.circuit import layout as L
from frogsim.circuit import actuators
from frogsim.circuit.valves import write_block
from frogsim.scenario import kinds
from frogsim.scenario.core import Scenario
from frogsim.scenario.motion import command_time, muscle_knots, output_times
from frogsim.scenario.schema import VALVE_STATES
from frogsim.scenario.view import Settings
from frogsim.physics.air import critical_pressure_ratio
from frogsim.physics.flow import main_pipe_branch_limit, tube_sonic_conductance


def build_schedule(programs: list, rate: float, charge_dead: float, discharge_dead: float):
    """Valve switching times and states: commands at controller samples, plus each valve's dead time.

    ``programs`` lists (muscle name, Program) in the model's order. Returns (sched_t (S,),
    sched_u (S, 2n), u0 (2n,), charge_open_times: list of arrays per muscle).
    """
    events = []
    opens = []
    names = [name for name, _ in programs]
    for i, (name, program) in enumerate(programs):
        ch_open = []
        prev = (0, 0)
        for t_cmd, state in program.steps:
            tq = command_time(t_cmd, rate)
            new = VALVE_STATES[state]
            if new[0] != prev[0]:
                events.append((tq + charge_dead, L.charge_valve(i), float(new[0])))
                if new[0]:
                    ch_open.append(tq + charge_dead)
            if new[1] != prev[1]:
                events.append((tq + discharge_dead, L.vent_valve(i), float(new[1])))
            prev = new
        opens.append(np.array(ch_open))
    sched_t, sched_u = schedule_from_events(events, np.zeros(L.valve_size(len(names))))
    return sched_t, sched_u, np.zeros(L.valve_size(len(names))), opens


def schedule_from_events(events, u_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Valve events (time [s], valve column, new state) -> (times (S,), states (S, nu)): from
    ``u_start``, the full valve vector after each distinct time (events closer than 1e-12 s are
    one time), in time order."""
    u = np.array(u_start, float)
    times, states = [], []
    for t, j, val in sorted(events):
        u[j] = val
        if times and abs(times[-1] - t) < 1e-12:
            states[-1] = u.copy()
        else:
            times.append(t)
            states.append(u.copy())
    return np.array(times, float), np.array(states, float).reshape(len(times), u.size)


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


def branch_limit_standard(s) -> float:
    """Paper-mode per-branch limit (of a Supply) as a standard volume flow [m^3/s]: the override
    or Eq. (9)."""
    if s.branch_limit is not None:
        return s.branch_limit
    return main_pipe_branch_limit(s.main_tube_inner_diameter, s.velocity_limit, s.main_tube_count,
                                  s.branch_count)


class Circuit(NamedTuple):
    """The circuit's constants: the globals g (G_*) and one row of mp (M_*) per muscle."""
    g: np.ndarray
    mp: np.ndarray


class Motion(NamedTuple):
    """The muscles' prescribed length paths, cubic Hermite knots per muscle (rows padded to a
    common length): times t [s], lengths L [m], slopes d [m/s] (n, K), knots per muscle n (n,)."""
    t: np.ndarray
    L: np.ndarray
    d: np.ndarray
    n: np.ndarray


class Schedule(NamedTuple):
    """The open-loop valve commands: switching times t (S,) [s], the valve states from each on u
    (S, 2n; NaN: a closed-loop controller's valve), the states before the first u0 (2n,), and each
    muscle's charge-valve opening times (a list of arrays)."""
    t: np.ndarray
    u: np.ndarray
    u0: np.ndarray
    charge_open_times: list


class Start(NamedTuple):
    """The initial state y0 (:mod:`frogsim.circuit.layout`) and the absolute tolerance of each entry."""
    y0: np.ndarray
    atol: np.ndarray


@dataclass
class PneumaticModel:
    """The engine's arrays (see :mod:`frogsim.circuit.layout`) built from one Scenario, in named
    groups: ``circuit`` (g, mp), ``motion`` (the length paths), ``schedule`` (the open-loop valve
    commands), ``start`` (y0, atol), the output times ``out_t`` and the sampled laws ``laws``
    (:mod:`frogsim.circuit.laws`). :attr:`rhs_model` is the right-hand side's group as
    :func:`frogsim.engine.integrator.advance` takes it. The arrays' old flat names (``g``,
    ``mot_t``, ``sched_u``, ``y0``, ...) read the groups' members."""
    scenario: Scenario
    names: list
    circuit: Circuit
    motion: Motion
    schedule: Schedule
    start: Start
    out_t: np.ndarray
    laws: np.ndarray = None

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def rhs_model(self) -> tuple:
        """(g, mp, mot_t, mot_L, mot_d, mot_n): advance's ``model`` group (a plain tuple)."""
        return tuple(self.circuit) + tuple(self.motion)

    g = property(lambda self: self.circuit.g)
    mp = property(lambda self: self.circuit.mp)
    mot_t = property(lambda self: self.motion.t)
    mot_L = property(lambda self: self.motion.L)
    mot_d = property(lambda self: self.motion.d)
    mot_n = property(lambda self: self.motion.n)
    sched_t = property(lambda self: self.schedule.t)
    sched_u = property(lambda self: self.schedule.u)
    u0 = property(lambda self: self.schedule.u0)
    charge_open_times = property(lambda self: self.schedule.charge_open_times)
    y0 = property(lambda self: self.start.y0)
    atol = property(lambda self: self.start.atol)


def build_model(scenario: Scenario) -> PneumaticModel:
    """Flatten a Scenario into the arrays the engine loops over.

    The arrays come in parts (:data:`PARTS`), each a pure function of the few top-level settings
    it declares (it reads them through a :class:`frogsim.scenario.view.Settings`, which refuses
    any other) and of earlier parts, and cached on them (frozen dataclasses hash by value): the
    motions, valve schedule and muscle rows (the muscles with their types and programs, the
    controller rate, the valves), the globals ``g`` (air, chambers, pump, supply, valves, and the
    heat switch from the muscle rows), the sampled laws, the initial state (chambers, muscles,
    tolerance) and the output grid. A variant
    that changes one setting rebuilds only the parts that read it, a batch of variants builds each
    distinct part once (:mod:`frogsim.engine.batch`), and the model equals a fresh build bit for
    bit. :func:`assemble` copies every array, so a model never shares arrays with another.
    """
    values, owner = scenario.__dict__, type(scenario)
    parts: dict = {}
    for name, names, deps, make in PARTS:
        parts[name] = make(Settings(values, names, owner), *(parts[d] for d in deps))
    return assemble(scenario, parts)


def _motion_stage(sc):
    """(muscle names, motion part (:func:`_motion_part`), muscle rows mp)."""
    names = tuple(sc.muscles)
    muscles = tuple((name, sc.muscles[name], sc.muscle_types[sc.muscles[name].type]) for name in names)
    files = tuple(_file_key(sc.base_dir, m) for _, m, _ in muscles)
    motion = _motion_part(muscles, sc.controller.rate, sc.valves.charge.dead_time,
                          sc.valves.discharge.dead_time, files, sc.base_dir)
    mp = _muscle_part(sc.valves, tuple(mt for _, _, mt in muscles)).copy()
    mp[:, L.M_FIXEDV] = motion[9]
    return names, motion, mp


def _globals_stage(sc, motion):
    """The globals g with the heat switch G_HEAT: 1 when some wall passes heat, the source's, the
    exhaust's or a muscle's (its row of mp, in the motion part), else 0. Set here, in the part,
    so that every runner sees it: the batched ones run the parts without assembling a model."""
    g = _globals_part(sc.air, sc.source, sc.exhaust, sc.pump, sc.supply, sc.valves)
    mp = motion[2]
    # every h >= 0, so some h > 0 when the largest is: a Python max over a few rows costs a
    # quarter of NumPy's compare and any
    if max(g[L.G_H_S], g[L.G_H_E], *mp[:, L.M_H].tolist()) > 0.0:
        g = g.copy()                  # the cached array is never written (its G_HEAT stays 0)
        g[L.G_HEAT] = 1.0
    return g


def _volumes_stage(sc, motion):
    """(muscle names, each muscle's volume at the start [m^3])."""
    names, parts, _ = motion
    return names, parts[8]


def _laws_stage(sc, g, volumes):
    """The table of sampled laws."""
    return _laws(sc, g, *volumes)


def _schedule_stage(sc, laws, motion):
    """The valve schedule's states, with the valves of closed-loop muscles left to their
    controllers."""
    names, parts, _ = motion
    sched_u = parts[5]
    if laws.ndim == 2 and laws.shape[0] and (laws[:, 0] != 1.0).any():     # 1-D: open loop
        # the valves of a muscle under a closed-loop controller are the controller's: the schedule
        # leaves them alone (NaN: "not set here", see frogsim.engine.integrator.advance)
        sched_u = sched_u.copy()
        for c in sc.controllers.values():
            if c.closed_loop:
                for m in c.driven():
                    i = names.index(m)
                    sched_u[:, L.muscle_valve_slice(i)] = np.nan
    return sched_u


def _state_stage(sc, volumes):
    names, vols = volumes
    return _state_part(sc.air, sc.source, sc.exhaust, tuple(sc.muscles[n].initial_pressure_gauge for n in names),
                       vols, sc.solver.rtol)


def _output_stage(sc):
    return _output_part(sc.duration, sc.output_interval)


#: The parts of a model: (name, top-level settings it reads, earlier parts it uses, maker).
PARTS = (
    ("motion", ("muscles", "muscle_types", "controller", "valves", "base_dir"), (), _motion_stage),
    ("volumes", (), ("motion",), _volumes_stage),
    ("g", ("air", "source", "exhaust", "pump", "supply", "valves"), ("motion",), _globals_stage),
    # with [firmware] a law's integer tables also read the run's length, the source's and the
    # exhaust's pressures, and its fault limits the muscles' names (frogsim.control.fixed)
    ("laws", ("valves", "controllers", "controller", "joints", "firmware", "duration", "source", "pump", "exhaust",
              "muscles"),
     ("g", "volumes"), _laws_stage),
    ("sched_u", ("controllers",), ("laws", "motion"), _schedule_stage),
    ("state", ("air", "source", "exhaust", "muscles", "solver"), ("volumes",), _state_stage),
    ("out_t", ("duration", "output_interval"), (), _output_stage),
)


def assemble(scenario: Scenario, parts: dict) -> PneumaticModel:
    """The model of a scenario from its parts (:data:`PARTS`), every array a fresh copy."""
    names, motion, mp = parts["motion"]
    mot_t, mot_L, mot_d, mot_n, sched_t, _, u0, opens, _, _ = motion
    laws, sched_u = parts["laws"], parts["sched_u"]
    y0, atol = parts["state"]
    g = parts["g"].copy()
    return PneumaticModel(scenario=scenario, names=list(names), circuit=Circuit(g, mp.copy()),
                          motion=Motion(mot_t.copy(), mot_L.copy(), mot_d.copy(), mot_n.copy()),
                          schedule=Schedule(sched_t.copy(), sched_u.copy(), u0.copy(), [o.copy() for o in opens]),
                          start=Start(y0.copy(), atol.copy()), out_t=parts["out_t"].copy(), laws=laws.copy())


def _laws(sc: Scenario, g: np.ndarray, names: tuple, volumes: tuple) -> np.ndarray:
    """The table of sampled laws: the pump's band, then the closed-loop controllers' rows, made by
    :mod:`frogsim.control.table` (registered with :mod:`frogsim.scenario.kinds`, so this layer
    does not import the control layer). The controllers' model of a muscle is its volume at the
    start."""
    return kinds.build_table(sc, g, names, volumes)


def _file_key(base_dir: str, m) -> tuple | None:
    """What identifies a joint-angle file's content (its folder, size and change time)."""
    if m.motion.kind != "joint_angles":
        return None
    st = (Path(base_dir) / m.motion.file).stat()
    return (base_dir, st.st_mtime_ns, st.st_size)


_CACHE = 4096


@functools.lru_cache(maxsize=_CACHE)
def _globals_part(air, source, exhaust, pump, supply, valves) -> np.ndarray:
    """The global parameter vector g (see :mod:`frogsim.circuit.layout`)."""
    R, k = air.gas_constant, air.heat_capacity_ratio
    patm = air.atmospheric_pressure_abs
    rho_ref = air.reference_density
    g = np.zeros(L.G_SIZE)
    g[L.G_K] = k
    g[L.G_R] = R
    g[L.G_PATM] = patm
    g[L.G_RHOREF] = rho_ref
    g[L.G_TREF] = air.reference_temperature
    g[L.G_TAMB] = air.ambient_temperature
    g[L.G_VS] = source.volume
    g[L.G_VE] = exhaust.volume
    g[L.G_PUMP_ENABLED] = 1.0 if pump.enabled and pump.displacement > 0 else 0.0
    g[L.G_PUMP_DISP] = pump.displacement
    g[L.G_PUMP_RMAX] = pump.max_pressure_ratio
    g[L.G_PUMP_ON] = patm + pump.on_below_gauge
    g[L.G_PUMP_OFF] = patm + pump.off_above_gauge
    g[L.G_SUPPLY_MODE] = {"none": L.SUPPLY_NONE, "paper": L.SUPPLY_PAPER,
                          "physical": L.SUPPLY_PHYSICAL}[supply.mode]
    g[L.G_BRANCH_LIMIT] = rho_ref * branch_limit_standard(supply)
    g[L.G_TUBE_C] = supply.main_tube_count * tube_sonic_conductance(
        supply.main_tube_inner_diameter, supply.discharge_coefficient, R, k, rho_ref, air.reference_temperature)
    g[L.G_TUBE_B] = critical_pressure_ratio(k)
    g[L.G_TUBE_RLAM] = valves.charge.laminar_ratio
    g[L.G_H_S], g[L.G_A_S] = source.heat_transfer_coefficient, source.inner_wall_area
    g[L.G_H_E], g[L.G_A_E] = exhaust.heat_transfer_coefficient, exhaust.inner_wall_area
    return g


@functools.lru_cache(maxsize=_CACHE)
def _muscle_part(valves, types: tuple) -> np.ndarray:
    """The per-muscle parameter matrix mp: the actuator's code and parameter block, written by its
    actuator type (:func:`frogsim.circuit.actuators.write_block`), dead volume, rest length, the
    wall's heat transfer coefficient, and the valve's code and parameter block, written by its valve
    type (:func:`frogsim.circuit.valves.write_block`; the fixed-volume column comes with the motions)."""
    mp = np.zeros((len(types), L.M_SIZE))
    for i, mt in enumerate(types):
        actuators.write_block(mp[i], mt)
        mp[i, L.M_DEAD] = mt.dead_volume
        write_block(mp[i], valves)
        mp[i, L.M_L0] = mt.nominal_length
        mp[i, L.M_H] = mt.heat_transfer_coefficient
    return mp


@functools.lru_cache(maxsize=_CACHE)
def _motion_part(muscles: tuple, rate: float, charge_dead: float, discharge_dead: float, files: tuple,
                 base_dir: str):
    """Motion knots (padded to a common length), the valve schedule with the knots as extra stops,
    each muscle's initial volume [m^3] and its fixed volume (0: the volume follows the length)."""
    n = len(muscles)
    knots = [muscle_knots(name, m, mt, rate, f, base_dir) for (name, m, mt), f in zip(muscles, files)]
    K = max(mk.t.size for mk in knots)
    mot_t, mot_L, mot_d = np.zeros((n, K)), np.zeros((n, K)), np.zeros((n, K))
    mot_n = np.zeros(n, dtype=np.int64)
    volumes = []
    for i, ((name, m, mt), mk) in enumerate(zip(muscles, knots)):
        nk = mk.t.size
        mot_t[i, :nk], mot_L[i, :nk], mot_d[i, :nk] = mk.t, mk.L, mk.dL
        mot_t[i, nk:] = mk.t[-1]
        mot_L[i, nk:] = mk.L[-1]
        mot_n[i] = nk
        if mk.fixed_volume > 0:
            volumes.append(mk.fixed_volume)
        else:
            volumes.append(actuators.settings_volume(mt, mk.L[0]) + mt.dead_volume)
    breaks = tuple(float(t) for mk in knots if mk.fixed_volume <= 0 for t in mk.t)
    sched_t, sched_u, u0, opens = _schedule_part(tuple((name, m.program) for name, m, _ in muscles), rate,
                                                 charge_dead, discharge_dead, breaks)
    fixed = np.array([mk.fixed_volume for mk in knots])
    return mot_t, mot_L, mot_d, mot_n, sched_t, sched_u, u0, opens, tuple(volumes), fixed


@functools.lru_cache(maxsize=_CACHE)
def _schedule_part(programs: tuple, rate: float, charge_dead: float, discharge_dead: float, breaks: tuple):
    """The valve schedule (:func:`build_schedule`) with the motion knots ``breaks`` as extra stops."""
    sched_t, sched_u, u0, opens = build_schedule(list(programs), rate, charge_dead, discharge_dead)
    stops = np.unique(np.asarray(breaks, float))
    sched_t, sched_u = add_breakpoints(sched_t, sched_u, u0, stops[stops > 0])
    return sched_t, sched_u, u0, opens


@functools.lru_cache(maxsize=_CACHE)
def _state_part(air, source, exhaust, muscle_p0: tuple, volumes: tuple, rtol: float):
    """Initial state y0 (every volume at ambient temperature, the source and the exhaust at their
    initial_temperature when one is given) and the absolute tolerances."""
    R, T_amb, patm = air.gas_constant, air.ambient_temperature, air.atmospheric_pressure_abs
    n = len(volumes)
    y0 = np.zeros(L.state_size(n))
    scale = np.zeros_like(y0)
    for i, (p0g, V0) in enumerate(zip(muscle_p0, volumes)):
        p0 = patm + (p0g if p0g is not None else exhaust.initial_pressure_gauge)
        y0[L.mass_index(i)] = p0 * V0 / (R * T_amb)
        y0[L.pressure_index(i)] = p0
        scale_m = patm * V0 / (R * T_amb)
        scale[L.mass_index(i)] = scale_m
        scale[L.pressure_index(i)] = patm
        scale[L.charged_index(i, n)] = scale_m
        scale[L.vented_index(i, n)] = scale_m
    ps0 = patm + source.initial_pressure_gauge
    pe0 = patm + exhaust.initial_pressure_gauge
    Ts0 = T_amb if source.initial_temperature is None else source.initial_temperature
    Te0 = T_amb if exhaust.initial_temperature is None else exhaust.initial_temperature
    y0[L.Y_MS] = ps0 * source.volume / (R * Ts0)
    y0[L.Y_PS] = ps0
    y0[L.Y_ME] = pe0 * exhaust.volume / (R * Te0)
    y0[L.Y_PE] = pe0
    scale[L.Y_MS] = patm * source.volume / (R * T_amb)
    scale[L.Y_PS] = patm
    scale[L.Y_ME] = patm * exhaust.volume / (R * T_amb)
    scale[L.Y_PE] = patm
    scale[L.pump_index(n)] = scale[L.Y_MS]
    return y0, rtol * scale


@functools.lru_cache(maxsize=_CACHE)
def _output_part(duration: float, interval: float) -> np.ndarray:
    return output_times(duration, interval)
