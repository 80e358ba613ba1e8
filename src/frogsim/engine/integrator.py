"""The one stepping driver of the circuit: pieces between valve switching times, steps of the
scenario's integration method inside them.

Valve states are piecewise constant: they change only at known times (open-loop commands sampled
on the controller grid plus the valve dead time) or at controller samples when a state-dependent
rule (the pump's pressure band, :mod:`frogsim.control.sampled`) is active. The driver stops
exactly at those times, so no step straddles a discontinuity; between them the steps are the
method's, as long as its step-size control lets them be. :func:`advance` is the one loop that
does this, for the pneumatics-only engine (:func:`run_schedule`, one call per run) and the coupled
engine (:mod:`frogsim.engine.coupled_kernel`, one call per MuJoCo step).

The integration method is a family (:mod:`frogsim.engine.methods`, one module each): a method is
its step with its error estimate, its continuous extension and its step-size control
(:mod:`frogsim.engine.stepsize`). The driver calls them through the dispatch below, assembled at
import from the registry as a chain of compiled closures inlined into the driver (as the
controller kinds' :func:`frogsim.control.sampled.law_mode`), the default method's branch first; a
run names its method by the code at the head of its parameter block (``solver``'s last entry,
:func:`frogsim.engine.methods.parameter_block`), and a code no method declares stops the run with
an error. The default, "dopri-rosenbrock", is adaptive Dormand-Prince 5(4) with a Rosenbrock
method on stiff stretches (:mod:`frogsim.engine.methods.dopri_rosenbrock`); "rk4" steps at a fixed
step (:mod:`frogsim.engine.methods.rk4`).
"""
from __future__ import annotations

import math

import numpy as np
from frogsim._jit import jit, jit_alloc, jit_step
from frogsim._registry import dispatch

from frogsim.circuit.actuators import check_codes
from frogsim.circuit.layout import (flows_size, muscle_count, physical_size, pump_entry, valve_muscles, valve_size,
                                   work_size)
from frogsim.circuit.rhs import rhs
from frogsim.control.sampled import (CS_PUMP, apply_due, next_due_time, next_sample_time, sample_controllers,
                                    start_controllers)
from frogsim.engine import methods
# the driver state's columns (D_*, STATS_SIZE) are laid out with the methods' (frogsim.engine.methods.spec)
from frogsim.engine.methods.spec import (D_ERR, D_F_VALID, D_H, D_M0, D_M_COUNT, D_OUT, D_PAUSE, D_REUSE_F, D_SI,
                                         D_SIZE, D_T, PART_ARGS, R_F, R_FN, R_OWN, R_RC1, R_RC2, R_RC3, R_RC4, R_YN,
                                         R_YS, ROWS, STATS_SIZE)
from frogsim.engine.stepsize import EPS

STATUS_OK = 0
STATUS_STEP_UNDERFLOW = 1
STATUS_NOT_FINITE = 2
STATUS_MAX_STEPS = 3
STATUS_PAUSED = 4        # stopped after ds[D_PAUSE] accepted steps, to be resumed (not a failure)
STATUS_NONPHYSICAL = 5   # an accepted step left an air mass or pressure <= 0 (or NaN): ds[D_T], y show it
STATUS_ROWS_UNWRITTEN = 6  # the run reached its end with output rows it never wrote (a grid past the end)
STATUS_TEXT = {STATUS_STEP_UNDERFLOW: "step size fell below 1e-14 s",
               STATUS_NOT_FINITE: "the state became non-finite (NaN or inf)",
               STATUS_MAX_STEPS: "more than 50 million steps",
               STATUS_NONPHYSICAL: "an air mass or pressure became zero or negative",
               STATUS_ROWS_UNWRITTEN: "the run ended with output rows it never wrote (an output time "
                                      "past the end of the run)"}



# --- the methods' dispatch, generated from the registry (frogsim.engine.methods, frogsim._registry.dispatch) --
_METHODS = methods.ordered()
#: one trial step of the run's method (its error estimate, its continuous extension made or not); the
#: one dispatch that refuses a code no method declares (the others' last branch takes any code)
trial = dispatch([(m.code, m.step) for m in _METHODS], PART_ARGS["step"],
                 unknown="advance: the solver's parameter block names an integration method code that no method "
                         "declares (frogsim.engine.methods)")
#: the continuous extension of the run's method's last step
dense_of = dispatch([(m.code, m.dense) for m in _METHODS], PART_ARGS["dense"], returns=False)
#: the run's method's step-size control: the next trial step, after an accepted, after a rejected step
propose = dispatch([(m.code, m.control.propose) for m in _METHODS], PART_ARGS["propose"])
accepted = dispatch([(m.code, m.control.accepted) for m in _METHODS], PART_ARGS["accepted"])
rejected = dispatch([(m.code, m.control.rejected) for m in _METHODS], PART_ARGS["rejected"])
#: the run's method's restart after a command change at a piece's end (nothing for a method without one)
restart = dispatch([(m.code, m.restart) for m in _METHODS if m.restart is not None], PART_ARGS["restart"],
                   returns=False,
                   optional=True)

@jit_step
def ds_size(ny):
    """Length of the driver state ds for a state of ny entries: the D_* columns, then the method's
    kept entries (ny x ny + ny: the default's Jacobian df/dy and df/dt), then the kept dy/dt (ny),
    then the scratch space of :func:`advance` (:func:`_scratch_size`; its contents are not
    carried from one call to the next)."""
    return D_SIZE + ny * ny + 2 * ny + _scratch_size(ny)


@jit_step
def _scratch_size(ny):
    """Entries of advance's scratch space for a state of ny entries: ROWS vectors (the driver's
    and the method's, :mod:`frogsim.engine.methods.spec`), a scratch ny x ny matrix, the previous
    valve states and the right-hand side's aux and work vectors (:mod:`frogsim.circuit.layout`:
    :func:`~frogsim.circuit.layout.valve_size`, :func:`~frogsim.circuit.layout.flows_size`,
    :func:`~frogsim.circuit.layout.work_size`), n the muscles of a state of ny entries
    (:func:`frogsim.circuit.layout.muscle_count`)."""
    n = muscle_count(ny)
    return ROWS * ny + ny * ny + valve_size(n) + flows_size(n) + work_size(n)


@jit_step
def _dense(y, rc1, rc2, rc3, rc4, th, out):
    """The continuous extension at th in [0, 1] of the step: out = y(t + th h)."""
    th1 = 1.0 - th
    for j in range(y.size):
        out[j] = y[j] + th * (rc1[j] + th1 * (rc2[j] + th * (rc3[j] + th1 * rc4[j])))


@jit_step
def _samples_in_step(laws, mp, cs, t, t_new, h, y, yn, dense, ys, u):
    """The controllers' samples t_k inside an accepted step (t, t_new] of length h, in order,
    each taken from the step's continuous extension (``dense`` = rc1..rc4, made by the driver
    before when a sample falls inside the step: :func:`_needs_dense`) into ys, or from the step's
    solution yn at t_new. A sample whose command acts at once ends the step at t_k; a queued
    command due before the step's end ends it at its due time (see :func:`advance`).

    Returns (t_cut, refresh): where the step ends and whether a command changed.
    """
    rc1, rc2, rc3, rc4 = dense
    t_cut = t_new
    refresh = False
    t_s = next_sample_time(laws, cs)
    while t_s <= t_cut + EPS:
        if t_s >= t_new - EPS:
            t_s = t_new
            for j in range(y.size):
                ys[j] = yn[j]
        else:
            _dense(y, rc1, rc2, rc3, rc4, (t_s - t) / h, ys)
        if sample_controllers(laws, mp, t_s, ys, u, cs):
            refresh = True
            if t_s < t_new - EPS:
                t_cut = t_s
                break
        t_due = next_due_time(laws, cs)
        if t_due < t_cut - EPS:
            t_cut = max(t_due, t)
        t_s = next_sample_time(laws, cs)
    return t_cut, refresh


@jit_step
def _needs_dense(laws, cs, t_new, out_t, out_i):
    """Whether an accepted step ending at t_new needs its continuous extension: a controller's
    sample falls inside it (before t_new - EPS), or an output row at or before t_new (a step the
    samples cut short has a sample inside it)."""
    return next_sample_time(laws, cs) < t_new - EPS or (out_i < out_t.size and out_t[out_i] <= t_new)


@jit_step
def _accept(laws, mp, cs, t, t_new, h, y, f, yn, fn, dense, ys, u, u_prev, pump_on, out, out_i, stats):
    """An accepted step of length h from t to t_new: the controllers' samples inside the step
    (:func:`_samples_in_step`; the step may end early at t_cut), the output rows it covers (from
    the continuous extension ``dense``, made before when :func:`_needs_dense`), y and f moved on (f = dy/dt at the step's end, fn, unless a command changed) and the
    physical check. The step-size control is the method's (:func:`advance` calls it after this).

    Returns (t, pump_on, out_i, refresh, status): the time reached, the pump's switch, the next
    output row, whether a command changed (the caller evaluates dy/dt again) and a STATUS_* code
    (STATUS_NONPHYSICAL when an air mass or pressure is no longer positive).
    """
    rc1, rc2, rc3, rc4 = dense
    out_t, out_y, out_u = out
    ny = y.size
    nu = u.size
    n_out = out_t.size
    n = valve_muscles(nu)
    status = STATUS_OK
    h_try = h
    # -- the controllers' samples inside the step, read from the continuous extension. A
    # command that acts at once (the pump's switch, a valve without dead time) or a
    # valve command that comes due before t_new ends the step there: the state at
    # that time is the continuous extension's, the rest of the step is dropped.
    for j in range(nu):
        u_prev[j] = u[j]
    pump_prev = pump_on
    t_cut, refresh = _samples_in_step(laws, mp, cs, t, t_new, h_try, y, yn, dense, ys, u)
    if t_cut < t_new - EPS:
        # the step ends at t_cut (a sample that changed a command, or a due time)
        _dense(y, rc1, rc2, rc3, rc4, (t_cut - t) / h_try, yn)
        t_new = t_cut
        apply_due(laws, t_new, u, cs)
        refresh = True
    pump_on = cs[CS_PUMP]
    while out_i < n_out and out_t[out_i] <= t_new:
        th = (out_t[out_i] - t) / h_try
        _dense(y, rc1, rc2, rc3, rc4, th, out_y[out_i])
        for j in range(nu):
            out_u[out_i, j] = u_prev[j]
        out_u[out_i, pump_entry(n)] = pump_prev
        out_i += 1
    for j in range(ny):
        y[j] = yn[j]
        f[j] = fn[j]
    t = t_new
    stats[0] += 1
    for j in range(physical_size(n)):
        if not y[j] > 0.0:          # every air mass and pressure; NaN fails too
            status = STATUS_NONPHYSICAL
    return t, pump_on, out_i, refresh, status


@jit_alloc
def start(t0, h0, y, u, mp, commands):
    """Driver state ``ds`` and controller state ``cs`` of a run that starts at t0.

    ``commands`` = (sched_t, sched_u, laws, ctrl_dt); ``mp`` the model's muscle rows (a law that
    models the valves reads their constants there). The schedule entries due at t0 are written
    into u, the controllers take the sample at or just before t0 (:func:`frogsim.control.sampled
    .start_controllers`), the first trial step is h0 [s].
    """
    sched_t, sched_u, laws, ctrl_dt = commands
    check_codes(mp)          # the muscles' actuator codes, once a run (the right-hand side trusts them)
    ds = np.zeros(ds_size(y.size))
    ds[D_T] = t0
    ds[D_H] = h0
    ds[D_ERR] = 1e-4
    si = 0
    while si < sched_t.size and sched_t[si] <= t0 + EPS:
        for j in range(u.size):
            if sched_u[si, j] == sched_u[si, j]:      # NaN: a valve under closed-loop control
                u[j] = sched_u[si, j]
        si += 1
    ds[D_SI] = si
    return ds, start_controllers(laws, mp, t0, y, u, ctrl_dt)


@jit
def advance(t_end, y, u, ds, cs, model, commands, solver, out, stats):
    """Advance the circuit's state y from ds[D_T] to t_end: the one stepping loop of frogsim.

    The span is cut at every valve-schedule time and at every due time of a queued valve command
    (:func:`frogsim.control.sampled.next_due_time`), times closer than EPS to each other or to
    t_end counting as one. Each piece is integrated by the run's method's steps (``solver``'s
    parameter block names it; :data:`trial`) with the valve states u and the pump's switch held,
    where its step-size control puts them (:data:`propose`, :data:`accepted`, :data:`rejected`):
    adaptive steps, or steps on a fixed grid, the last shortened to end on the piece's end
    exactly; the step size carries over from piece to piece. At a piece's end the schedule
    entries and the queued commands due are written into u, and if a command changed the
    right-hand side is evaluated again (the FSAL derivative no longer holds) and the method
    restarts (:data:`restart`: the default goes back to its explicit steps).

    Controller samples are not stops. After each accepted step the samples t_k inside it
    (:func:`frogsim.control.sampled.next_sample_time`) are taken in order from the step's
    continuous extension (:func:`frogsim.control.sampled.sample_controllers`). A sample whose
    command acts at once (the pump's switch, a valve without dead time), or whose valve command
    comes due before the step's end, ends the step there: the state at that time is the
    continuous extension's (as an event-locating solver restarts from its interpolant) and the
    rest of the step is dropped. Steps are therefore as long as accuracy allows while the
    controllers hold their commands, and commands still change only at t_k (plus dead time).
    The Python-controller driver (:func:`frogsim.engine.pneumatic.run_python_controller`) calls
    this with t_end on every sample, so there each sample is a step's end.

    dy/dt is evaluated at entry: the caller may have changed the model since the last call. A
    caller that changed nothing dy/dt reads at (t, y) sets ds[D_REUSE_F] = 1, and the call starts
    from the dy/dt the last call ended with (kept in ds; the coupled engine, whose new length path
    starts with the old one's value and slope). Time reached, step size, the step-size
    control's memory, the method's memory (columns D_M0.., its kept Jacobian), schedule index
    and output row are carried in ``ds`` (columns D_*), the controllers'
    memory and the pump's switch in ``cs``, so a run can be advanced in as many calls as wanted:
    the coupled engine calls this once per MuJoCo step, :func:`run_schedule` once for the run.

    ``model`` = (g, mp, mot_t, mot_L, mot_d, mot_n), the right-hand side's circuit and length
    paths; ``commands`` = (sched_t, sched_u, laws, ctrl_dt); ``solver`` = (rtol, atol, max_step,
    par), ``par`` the method's parameter block (:func:`frogsim.engine.methods.parameter_block`:
    its code, then its settings, e.g. the fixed step [s]);
    ``out`` = (out_t, out_y, out_u): the rows from ds[D_OUT] on whose times fall inside the span
    are filled by dense output (state, valve states and the pump's switch); ``stats``
    accumulates [accepted steps, rejected steps, rhs evaluations, accepted Rosenbrock steps].

    With ds[D_PAUSE] > 0 the call returns STATUS_PAUSED once stats[0] has reached it, after an
    accepted step inside a piece or at a piece's end (after its commands); calling again goes on
    with exactly the steps an uninterrupted call would take, since dy/dt, evaluated again at
    entry, is a pure function of t, y, u and cs (the caller's clock and progress bar live between
    the calls).

    Returns a STATUS_* code; on failure ds[D_T] and y are the last accepted step's.
    """
    if stats.size < STATS_SIZE or ds.size < ds_size(y.size):
        raise ValueError("advance: stats needs STATS_SIZE entries and ds D_SIZE + ny^2 + 2 ny (make them with "
                         "begin or start)")
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    sched_t, sched_u, laws, ctrl_dt = commands
    rtol, atol, max_step, par = solver
    code = par[0]
    ny = y.size
    nu = u.size
    ns = sched_t.size
    n = mp.shape[0]
    # the scratch space at ds's end, cut into the driver's vectors (views, no copies): nothing is
    # allocated per call (the coupled engine calls this once per MuJoCo step)
    scratch = ds[D_SIZE + ny * ny + 2 * ny:]
    vec = scratch[:ROWS * ny].reshape((ROWS, ny))         # the driver's rows, then the method's own
    f, fn, yn, ys = vec[R_F], vec[R_FN], vec[R_YN], vec[R_YS]
    dense = (vec[R_RC1], vec[R_RC2], vec[R_RC3], vec[R_RC4])
    rc1, rc2, rc3, rc4 = dense
    # the method's own rows, cut once a call (a method indexes this tuple with constants)
    own = (vec[R_OWN], vec[R_OWN + 1], vec[R_OWN + 2], vec[R_OWN + 3], vec[R_OWN + 4], vec[R_OWN + 5],
           vec[R_OWN + 6], vec[R_OWN + 7], vec[R_OWN + 8], vec[R_OWN + 9], vec[R_OWN + 10], vec[R_OWN + 11],
           vec[R_OWN + 12], vec[R_OWN + 13])
    mat = scratch[ROWS * ny:ROWS * ny + ny * ny].reshape((ny, ny))
    # the method's entries kept from call to call: a matrix and a vector (the default's Jacobian)
    kmat = ds[D_SIZE:D_SIZE + ny * ny].reshape((ny, ny))
    kvec = ds[D_SIZE + ny * ny:D_SIZE + ny * ny + ny]
    o = ROWS * ny + ny * ny
    u_prev = scratch[o:o + nu]
    o += nu
    aux = scratch[o:o + flows_size(n)]
    o += flows_size(n)
    work = scratch[o:o + work_size(n)]
    t = ds[D_T]
    h = ds[D_H]
    err_old = ds[D_ERR]
    out_i = int(ds[D_OUT])
    status = STATUS_OK
    pump_on = cs[CS_PUMP]
    f_kept = ds[D_SIZE + ny * ny + ny:D_SIZE + ny * ny + 2 * ny]
    if ds[D_REUSE_F] > 0.5 and ds[D_F_VALID] > 0.5:
        for j in range(ny):
            f[j] = f_kept[j]
    else:
        rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
        stats[2] += 1
    ds[D_F_VALID] = 0.0
    while t < t_end - EPS:
        # -- the piece's end: t_end, the next schedule entry or the next queued valve command ----
        t_seg = t_end
        si = int(ds[D_SI])
        if si < ns and sched_t[si] < t_end - EPS:
            t_seg = max(sched_t[si], t)
        t_due = next_due_time(laws, cs)
        if t_due < t_seg - EPS:
            t_seg = max(t_due, t)
        # -- the method's steps from t to exactly t_seg ------------------------------------------
        while t < t_seg:
            h, h_try, t_new, last = propose(code, par, t, t_seg, h, max_step)
            err, a1, a2, dense_ready = trial(code, t, h_try, t_new, y, f, yn, fn, u, pump_on, model, atol, rtol, par,
                                             ds, own, dense, mat, kmat, kvec, aux, work, stats)
            if not math.isfinite(err):
                # a non-finite trial: the control shrinks the step and retries (a fixed step: it
                # returns 0); give up at step underflow
                stats[1] += 1
                h = rejected(code, ds, par, h_try, err)
                if h < 1e-14 * max(1.0, abs(t)):
                    status = STATUS_NOT_FINITE
                    break
                continue
            if err <= 1.0:
                # the continuous extension, for the samples and output rows inside the step (made
                # by the step already, or only when one falls inside it: a step that ends on its
                # sample, as every coupled-engine step does, needs none)
                if not dense_ready and _needs_dense(laws, cs, t_new, out[0], out_i):
                    dense_of(code, h_try, y, yn, f, fn, own, rc1, rc2, rc3, rc4)
                t, pump_on, out_i, refresh, status = _accept(laws, mp, cs, t, t_new, h_try, y, f, yn, fn, dense, ys,
                                                             u, u_prev, pump_on, out, out_i, stats)
                if status != STATUS_OK:
                    break
                h_next, err_old = accepted(code, ds, par, h_try, err, err_old, a1, a2, refresh, stats)
                if refresh:
                    # commands changed (or the step was cut): dy/dt at the new point under them
                    rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
                    stats[2] += 1
                h = max(h, h_next) if (last and t >= t_seg) else h_next
                if t < t_seg:
                    # a sample in the step may have queued a command due before the piece's end
                    t_due = next_due_time(laws, cs)
                    if t_due < t_seg - EPS:
                        t_seg = max(t_due, t)
                if t < t_seg and ds[D_PAUSE] > 0 and stats[0] >= ds[D_PAUSE]:
                    # a pause inside a piece: everything the next call needs is in y, ds and cs
                    # (dy/dt is a pure function of them), so pausing changes no step
                    status = STATUS_PAUSED
                    break
            else:
                stats[1] += 1
                h = rejected(code, ds, par, h_try, err)
                if h < 1e-14 * max(1.0, abs(t)):
                    status = STATUS_STEP_UNDERFLOW
                    break
            if stats[0] + stats[1] > 50_000_000:
                status = STATUS_MAX_STEPS
                break
        if status != STATUS_OK:
            break
        # -- at t_seg: the schedule's commands due and the queued valve commands due ------------
        t = t_seg
        changed = False
        while si < ns and sched_t[si] <= t + EPS:
            for j in range(nu):
                if sched_u[si, j] != sched_u[si, j]:
                    continue            # NaN: the valve is a closed-loop controller's, not the schedule's
                if u[j] != sched_u[si, j]:
                    changed = True
                u[j] = sched_u[si, j]
            si += 1
        ds[D_SI] = si
        if apply_due(laws, t, u, cs):
            changed = True
        if changed:
            restart(code, ds)                 # (before a pause: ds carries it to the next call)
        if ds[D_PAUSE] > 0 and stats[0] >= ds[D_PAUSE] and t < t_end - EPS:
            status = STATUS_PAUSED            # between pieces: the next call starts the next one
            break
        if changed:
            rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, f, aux, work)
            stats[2] += 1
    ds[D_T] = t
    ds[D_H] = h
    ds[D_ERR] = err_old
    ds[D_OUT] = out_i
    if status == STATUS_OK or status == STATUS_PAUSED:
        for j in range(ny):
            f_kept[j] = f[j]
        ds[D_F_VALID] = 1.0
    return status


@jit_alloc
def begin(y0, t0, u0, mp, laws, sched_t, sched_u, ctrl_dt, out_t, h0):
    """Everything a run from t0 needs before its first :func:`advance`: output arrays (the rows at
    or before t0 hold the initial state), the state and valve vectors, the driver and controller
    states, the step statistics and the commands tuple. ``laws`` is the run's table of sampled
    laws (``PneumaticModel.laws``: the pump's band and the closed-loop controllers), ``mp`` the
    model's muscle rows (the valves' constants a law's valve model reads)."""
    ny = y0.size
    nu = u0.size
    n_out = out_t.size
    out_y = np.empty((n_out, ny))
    out_u = np.empty((n_out, flows_size(valve_muscles(nu))))
    stats = np.zeros(STATS_SIZE, dtype=np.int64)
    y = y0.copy()
    u = u0.copy()
    commands = (sched_t, sched_u, laws, ctrl_dt)
    ds, cs = start(t0, h0, y, u, mp, commands)
    out_i = 0
    while out_i < n_out and out_t[out_i] <= t0:
        for j in range(ny):
            out_y[out_i, j] = y[j]
        for j in range(nu):
            out_u[out_i, j] = u[j]
        out_u[out_i, pump_entry(valve_muscles(nu))] = cs[CS_PUMP]
        out_i += 1
    ds[D_OUT] = out_i
    return out_y, out_u, y, u, ds, cs, stats, commands


@jit_step
def finished_status(status, ds, n_out):
    """A run's final status: STATUS_ROWS_UNWRITTEN in place of STATUS_OK when the run reached its
    end but its output row counter ds[D_OUT] stopped short of the n_out rows (empty rows left
    uninitialised are never returned as results)."""
    if status == STATUS_OK and ds[D_OUT] < n_out:
        return STATUS_ROWS_UNWRITTEN
    return status


@jit_alloc
def run_schedule(y0, u0, t0, t_end, model, commands, solver, out_t, h0, pause_every):
    """Integrate from t0 to t_end under an open-loop valve schedule and the run's sampled laws
    (the pump's band and the closed-loop controllers, ``PneumaticModel.laws``): :func:`begin`, then
    one :func:`advance`, whose groups it takes: ``model`` = (g, mp, mot_t, mot_L, mot_d, mot_n),
    ``commands`` = (sched_t, sched_u, laws, ctrl_dt), ``solver`` = (rtol, atol, max_step, par).

    ``sched_t`` (sorted) are the times at which valve states become ``sched_u[k]``; before the
    first, ``u0`` holds. Entries may repeat the current state: they only make the integrator stop
    there (used for kinks in the prescribed motion). Output rows at out_t (sorted); the rows at or
    before t0 hold the initial state. ``pause_every`` > 0 pauses after that many accepted steps
    (STATUS_PAUSED; go on with :func:`advance` and the returned u, ds, cs); 0 never pauses.

    Returns (out_y, out_u, y_end, stats, status, t_reached, cs, u, ds).
    """
    sched_t, sched_u, laws, ctrl_dt = commands
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    out_y, out_u, y, u, ds, cs, stats, commands = begin(y0, t0, u0, mp, laws, sched_t, sched_u, ctrl_dt, out_t, h0)
    ds[D_PAUSE] = pause_every
    status = advance(t_end, y, u, ds, cs, model, commands, solver, (out_t, out_y, out_u), stats)
    status = finished_status(status, ds, out_t.size)
    return out_y, out_u, y, stats, status, ds[D_T], cs, u, ds


def solver_group(solver, atol) -> tuple:
    """The driver's ``solver`` group of a scenario's ``[solver]`` settings (``solver``, a
    :class:`frogsim.scenario.schema.Solver`) and the model's absolute tolerances ``atol``:
    (rtol, atol, max_step, par), ``par`` its method's parameter block."""
    return (solver.rtol, atol, solver.max_step, methods.parameter_block(solver.method))
