"""The pneumatics-only engine: muscle lengths prescribed (the paper's Figure 8 model).

:func:`simulate` runs one scenario and checks what it returns: every air mass and pressure in the
output finite and positive, every muscle volume positive (else SimulationError naming the
quantity, its value and the time). The driver pauses every STEPS_PER_CALL accepted steps
(:data:`frogsim.engine.integrator.STATUS_PAUSED`), which changes no step: between calls the wall
clock is read, a run that has taken more than a few seconds shows a progress bar on stderr, and a
run past ``solver.max_wall_time`` stops with a hint at the cause (steps held to
``solver.max_step``, or a stiff circuit: a tiny chamber behind a large valve, whose transients need
steps of its time constant). Every run is bit for bit the same as in the
batched engine (:mod:`frogsim.engine.batch`), however many calls it took.
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from frogsim.circuit import actuators
from frogsim.circuit import layout as L
from frogsim.circuit.model import PneumaticModel, build_model
from frogsim.scenario.core import Scenario
from frogsim.control.table import L_DEAD_C, L_DEAD_D, L_KIND, L_MUSCLE, L_PATM, L_SIZE
from frogsim.control.sampled import (B_SENSED, CS_SAMPLE, KIND_EXTERNAL, KIND_PUMP_BAND, command_from_python,
                                     law_block, next_control_time)
from frogsim.engine.integrator import (D_OUT, D_PAUSE, D_T, EPS, STATUS_NONPHYSICAL, STATUS_OK, STATUS_PAUSED,
                                       STATUS_ROWS_UNWRITTEN, STATUS_TEXT, advance, begin,
                                       solver_group)
from frogsim.engine.result import Result
from frogsim.engine.run_result import valve_switchings
from frogsim.errors import SimulationError

STEPS_PER_CALL = 20_000       # accepted steps between two looks at the clock (about 10-50 ms)
PROGRESS_AFTER_S = 2.0        # a run still going after this long (or half its limit) shows a progress bar


def _as_model(what) -> PneumaticModel:
    if isinstance(what, PneumaticModel):
        return what
    if isinstance(what, Scenario):
        return build_model(what)
    from frogsim.scenario.load import load_scenario
    return build_model(load_scenario(what))


def _state_labels(model: PneumaticModel) -> list[tuple[int, str, str]]:
    """(state index, label, unit) of every air mass and pressure (quantities that must stay > 0)."""
    labels = L.state_labels(model.names)
    return [(j, *labels[j]) for j in range(L.physical_size(model.n))]


def _describe_state(model: PneumaticModel, y: np.ndarray) -> str:
    bad = [f"{lab} = {y[j]:.4g}" for j, lab, _ in _state_labels(model) if not np.isfinite(y[j]) or y[j] <= 0]
    return "; ".join(bad) if bad else "all states finite and positive"


def check_volumes(model: PneumaticModel) -> None:
    """SimulationError if a muscle's prescribed volume is not positive at some time.

    A muscle's length moves monotonically between its motion knots and Eq. (5)'s volume is concave
    in the length, so the knots bound the volume over the whole run.
    """
    mp = model.circuit.mp
    mot_t, mot_L, _, mot_n = model.motion
    for i, name in enumerate(model.names):
        fixed = mp[i, L.M_FIXEDV]
        if fixed > 0.0:
            continue
        actuators.REGISTRY.by(mp[i, L.M_ACT])     # KeyError naming the codes: an unknown type, before the run
        nk = int(mot_n[i])
        vols = np.empty(nk)
        actuators.knot_volumes(mp, i, mot_L, nk, vols)
        for k in range(nk):
            v = float(vols[k])
            if not (math.isfinite(v) and v > 0.0):
                raise SimulationError(f"scenario {model.scenario.name!r}: non-physical state at "
                                      f"t = {mot_t[i, k]:.6g} s: {name} volume = {v:.4g} m^3 "
                                      "(must be positive; check the muscle type's geometry)")


def check_state(model: PneumaticModel, t: np.ndarray, y: np.ndarray) -> None:
    """SimulationError naming the first output time at which an air mass or pressure is not
    finite and positive (a temperature T = p V/(m R) then is not either)."""
    labels = _state_labels(model)
    cols = y[:, [j for j, _, _ in labels]]
    good = np.isfinite(cols) & (cols > 0.0)
    if good.all():
        return
    row = int(np.argmin(good.all(axis=1)))
    col = int(np.argmin(good[row]))
    _, label, unit = labels[col]
    raise SimulationError(f"scenario {model.scenario.name!r}: non-physical state at t = {t[row]:.6g} s: "
                          f"{label} = {cols[row, col]:.4g} {unit} (must be finite and positive; "
                          f"{_describe_state(model, y[row])})")


def _check_status(model: PneumaticModel, status: int, t_reached: float, y_end) -> None:
    if status == STATUS_NONPHYSICAL:          # the quantity, its value and the time
        check_state(model, np.array([t_reached]), np.asarray(y_end)[None, :])
    if status != STATUS_OK:
        raise SimulationError(f"scenario {model.scenario.name!r}: integration stopped at t = {t_reached:.6g} s: "
                              f"{STATUS_TEXT.get(status, status)} ({_describe_state(model, y_end)})")


def slow_run_hint(model: PneumaticModel, t_reached: float, steps: int) -> str:
    """Why a run is slow, in words: its steps held to ``solver.max_step`` (mean step at least half
    of it), else the stiffest chamber (:func:`stiffness_hint`)."""
    max_step = model.scenario.solver.max_step
    mean = t_reached / max(steps, 1)
    if mean >= 0.5 * max_step:
        return (f"the mean step {mean:.2g} s is held to solver.max_step = {max_step:.3g} s; raise "
                f"solver.max_step or solver.max_wall_time, or shorten the duration")
    return stiffness_hint(model)


def stiffness_hint(model: PneumaticModel) -> str:
    """The chamber whose fill/empty time constant tau = V / (k p_ref C) is smallest, in words.

    With choked flow through a valve of sonic conductance C (ISO 6358: q = C p rho_ref), a chamber
    of volume V changes its pressure at a relative rate k p_ref C / V; an explicit solver needs
    steps no longer than about that time constant while it is changing (the driver switches to an
    L-stable Rosenbrock method where the chamber only rests, see
    :mod:`frogsim.engine.integrator`).
    """
    sc = model.scenario
    k = sc.air.heat_capacity_ratio
    p_ref = sc.air.reference_pressure_abs
    n = len(model.names)
    c_in, c_out = sc.valves.charge.sonic_conductance, sc.valves.discharge.sonic_conductance
    cands = [(sc.source.volume, n * c_in, "the source volume", "source.volume and valves.charge.sonic_conductance"),
             (sc.exhaust.volume, n * c_out, "the exhaust volume",
              "exhaust.volume and valves.discharge.sonic_conductance")]
    for i, name in enumerate(model.names):
        mt = sc.muscle_types[sc.muscles[name].type]
        fixed = model.mp[i, L.M_FIXEDV]
        v = fixed if fixed > 0 else math.pi * mt.inner_diameter ** 2 * mt.nominal_length / 4 + mt.dead_volume
        cands.append((v, max(c_in, c_out), f"muscle {name}'s volume",
                      f"muscle_types.{sc.muscles[name].type} and the valves' sonic_conductance"))
    v, c, what, paths = min(cands, key=lambda e: e[0] / (k * p_ref * e[1]))
    tau = v / (k * p_ref * c)
    return (f"{what} {v:.3g} m^3 behind a sonic conductance of {c:.3g} m^3/(s Pa) fills or empties with "
            f"a time constant of about {tau:.2g} s, which makes the circuit stiff (its transients "
            f"need steps about that short); raise solver.max_wall_time, shorten the duration or check {paths}")


def simulate(scenario, h0: float = 1e-4, *, max_wall_s: float | None = None,
             progress: bool | None = None, controller=None) -> Result:
    """Run one scenario (a Scenario, a built model, a TOML path or a dict) and return its Result.

    ``max_wall_s`` [s] overrides the scenario's ``solver.max_wall_time``; ``progress`` False hides
    the progress bar a long run shows on stderr. Raises SimulationError naming the time and the
    offending quantity if integration fails, the state turns non-physical (a mass, pressure or
    volume not positive) or the run exceeds its wall-time limit (with a hint at the stiff part).

    ``controller``: a Python function ``fn(t, obs) -> commands`` called at every controller sample
    instead of the scenario's compiled closed-loop laws (see :func:`run_python_controller`).
    """
    model = _as_model(scenario)
    if controller is not None:
        return run_python_controller(model, controller, h0, max_wall_s=max_wall_s)
    sc = model.scenario
    limit = sc.solver.max_wall_time if max_wall_s is None else float(max_wall_s)
    check_volumes(model)
    T = sc.duration
    wall0 = time.perf_counter()
    ctrl_dt = 1.0 / sc.controller.rate
    # begin, then the first STEPS_PER_CALL steps in one compiled call (most runs end within it):
    # the same two functions run_schedule calls, called from here so that a first run compiles
    # only them (run_schedule, the batched engine's entry, is compiled when a batch runs)
    y0, atol = model.start
    sched_t, sched_u, u0, _ = model.schedule
    out_y, out_u, y, u, ds, cs, stats, commands = begin(y0, 0.0, u0, model.mp, model.laws, sched_t, sched_u,
                                                        ctrl_dt, model.out_t, h0)
    ds[D_PAUSE] = STEPS_PER_CALL
    circuit = model.rhs_model
    solver = solver_group(sc.solver, atol)
    out = (model.out_t, out_y, out_u)
    status = advance(T, y, u, ds, cs, circuit, commands, solver, out, stats)
    bar = None
    try:
        while status == STATUS_PAUSED:
            elapsed = time.perf_counter() - wall0
            if elapsed > limit:
                raise SimulationError(f"scenario {sc.name!r}: stopped at t = {ds[D_T]:.6g} s of {T:g} s after "
                                      f"{elapsed:.0f} s of wall time (solver.max_wall_time = {limit:g} s) and "
                                      f"{int(stats[0])} steps: {slow_run_hint(model, ds[D_T], int(stats[0]))}")
            if bar is None and progress is not False and elapsed > min(PROGRESS_AFTER_S, limit / 2):
                from tqdm import tqdm
                bar = tqdm(total=T, file=sys.stderr, leave=False, desc=f"{sc.name[:30]} (simulated s)",
                           bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.4g}/{total:.4g} [{elapsed}<{remaining}]")
            if bar is not None:
                bar.update(ds[D_T] - bar.n)
            ds[D_PAUSE] = stats[0] + STEPS_PER_CALL
            status = advance(T, y, u, ds, cs, circuit, commands, solver, out, stats)
    finally:
        if bar is not None:
            bar.close()
    return _finish(model, status, ds, y, out_y, out_u, stats, cs)


def _finish(model, status, ds, y_end, out_y, out_u, stats, cs) -> Result:
    if status == STATUS_OK and int(ds[D_OUT]) < model.out_t.size:
        status = STATUS_ROWS_UNWRITTEN                # (run_schedule's finished_status, in Python)
    _check_status(model, status, ds[D_T], y_end)     # every accepted step was checked by the driver
    return Result(t=model.out_t, y=out_y, u=out_u, model=model,
                  stats={"steps": int(stats[0]), "rejected": int(stats[1]), "rhs_evaluations": int(stats[2]),
                         "stiff_steps": int(stats[3])},
                  switchings=valve_switchings(model.laws, model.names, cs))


def python_laws(model: PneumaticModel, every_muscle: bool = False) -> tuple[np.ndarray, list]:
    """The model's table of laws with every closed-loop controller's row turned into an external
    one (its sensor kept, its law left to Python), plus an external row for each muscle without a
    program (``every_muscle``: for every other muscle, its program included); and the muscle name
    of each external row, in row order."""
    # the open-loop 1-D row (or an empty one) as a table
    laws = (model.laws.reshape(-1, L_SIZE) if model.laws.ndim == 1 else model.laws).copy()
    names = []
    free = set(model.names)
    for c in range(laws.shape[0]):
        if laws[c, L_KIND] != KIND_PUMP_BAND:
            laws[c, L_KIND] = KIND_EXTERNAL
            names.append(model.names[int(laws[c, L_MUSCLE])])
    for name in model.names:
        if name in names or (model.scenario.muscles[name].program.steps and not every_muscle):
            free.discard(name)
    extra = [n for n in model.names if n in free]
    if extra:
        add = np.zeros((len(extra), laws.shape[1]))
        for r, n in enumerate(extra):
            add[r, L_KIND] = KIND_EXTERNAL
            add[r, L_MUSCLE] = model.names.index(n)
            add[r, L_DEAD_C] = model.scenario.valves.charge.dead_time
            add[r, L_DEAD_D] = model.scenario.valves.discharge.dead_time
            add[r, L_PATM] = model.g[L.G_PATM]
        laws = np.vstack([laws, add])
        names += extra
    return laws, names


def run_python_controller(model: PneumaticModel, fn, h0: float = 1e-4, *,
                          max_wall_s: float | None = None, every_muscle: bool = False) -> Result:
    """A run whose closed-loop muscles are driven by a Python function, sample by sample.

    At every controller sample t_k the driver stops (:func:`frogsim.engine.integrator.advance` to
    t_k), and ``fn(t_k, obs)`` is called with ``obs``: {muscle: pressure [Pa abs] as its sensor
    reads it (the controller section's sensor model, if any), "source": p_s, "exhaust": p_e}
    [Pa abs]. It returns {muscle: "charge" | "hold" | "vent"} (or +1, 0, -1) for any of the
    muscles without a program (under a ``[controllers]`` section); a muscle left out keeps its
    mode. ``obs["state"]`` is a copy of the whole state y at t_k (layout
    :mod:`frogsim.circuit.layout`). With ``every_muscle`` the function drives every muscle, those
    with a program too (their programs are not run: the firmware in the loop runs them, see
    :mod:`frogsim.export.sil`). The commands go through the same dead-time queue as the compiled laws', so the same
    law written in Python gives the same valve sequence (the states agree to the solver tolerance:
    this driver stops on every sample, the compiled one reads samples from dense output). Slow but
    flexible: see docs/control.md for the cost.
    """
    sc = model.scenario
    limit = sc.solver.max_wall_time if max_wall_s is None else float(max_wall_s)
    check_volumes(model)
    laws, ext = python_laws(model, every_muscle)
    rows = {n: c for c, n in zip([c for c in range(laws.shape[0]) if laws[c, L_KIND] == KIND_EXTERNAL], ext)}
    dt = 1.0 / sc.controller.rate
    T = sc.duration
    y0, atol = model.start
    sched_t, sched_u, u0, _ = model.schedule
    if every_muscle:                 # no program runs: every valve starts shut, waits for fn
        sched_t, sched_u, u0 = np.zeros(0), np.zeros((0, u0.size)), np.zeros_like(u0)
    out_y, out_u, y, u, ds, cs, stats, commands = begin(y0, 0.0, u0, model.mp, laws, sched_t, sched_u, dt,
                                                        model.out_t, h0)
    circuit = model.rhs_model
    solver = solver_group(sc.solver, atol)
    out = (model.out_t, out_y, out_u)

    def decide():
        t_k = cs[CS_SAMPLE] * dt
        obs = {n: float(cs[law_block(cs, c) + B_SENSED]) for n, c in rows.items()}
        obs["source"], obs["exhaust"] = float(y[L.Y_PS]), float(y[L.Y_PE])
        obs["state"] = y.copy()
        command_from_python(laws, rows, cs, fn(t_k, obs), t_k, u, ds[D_T])

    decide()
    wall0 = time.perf_counter()
    status = STATUS_OK
    n = 0
    while ds[D_T] < T - EPS:
        k = cs[CS_SAMPLE]
        t_stop = min(next_control_time(laws, cs, dt), T)
        status = advance(t_stop, y, u, ds, cs, circuit, commands, solver, out, stats)
        if status != STATUS_OK:
            break
        if cs[CS_SAMPLE] != k:
            decide()
        n += 1
        if n % 1000 == 0 and time.perf_counter() - wall0 > limit:
            raise SimulationError(f"scenario {sc.name!r}: stopped at t = {ds[D_T]:.6g} s of {T:g} s after "
                                  f"{limit:g} s of wall time (solver.max_wall_time)")
    result = _finish(model, status, ds, y, out_y, out_u, stats, cs)
    result.python_law = fn
    return result
