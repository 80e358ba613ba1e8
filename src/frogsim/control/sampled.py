"""Sampled controllers: the driver's side. Valve and pump commands decided from the state at the
controller's samples.

The controller samples the circuit at t_k = k ctrl_dt (ctrl_dt = 1 / rate: 1 ms at the paper's
1 kHz) and sets commands that hold until it changes them: the valves' states u (1 open, 0 shut)
and the pump's switch. Two sorts of controller give them:

* open-loop programs (the scenario's programs, the gait). Their commands are known before the run,
  so they are not evaluated while it runs: :func:`frogsim.circuit.model.build_schedule` turns them
  into the schedule (sched_t, sched_u) of the times at which the valves change (the sample that
  issues a command plus the valve's dead time), and the driver
  (:func:`frogsim.engine.integrator.advance`) applies it;
* sampled rules, evaluated at every sample from the state at that instant: the pump's pressure
  band (:func:`frogsim.control.signals.pump_band`), a hysteresis switch on the source pressure
  that acts at once (the pump's motor has no dead time in the model), and the closed-loop valve
  controllers of the scenario's ``[controllers]`` sections, each of which drives one muscle's two
  valves with its kind's law (one module per kind, :mod:`frogsim.control.kinds`; docs/control.md).

A run's sampled rules are the rows of a table ``laws[c, :]`` (a kind code and its parameters,
columns L_* of :mod:`frogsim.control.table`), built with the model (``PneumaticModel.laws``; the
pump's band alone: :func:`sampled_laws`); their memory (and the pump's switch) is a small array
``cs`` (layout in :mod:`frogsim.control.signals`) made by :func:`start_controllers`. The engines
call :func:`start_controllers` (once, at the start of a run), :func:`next_sample_time`,
:func:`next_due_time` and :func:`next_control_time` (where to stop next for the controllers),
:func:`sample_controllers` (called there; True when a command changed, so that the driver
evaluates the right-hand side again) and :func:`apply_due` (the queued commands due by a time);
the coupled engine also :func:`observe_joints`, the Python drivers :func:`command_from_python`,
the results :func:`switch_counts`.

A row's law is found by its kind code through :func:`law_mode`, and with ``[firmware]`` its
integer twin through :func:`fw_dispatch`: both are assembled at import from the registry of
kinds (:mod:`frogsim.control.kinds`: one branch per kind with a law, or with a twin, compiled as
the chain of closures :func:`_law_chain` and :func:`_twin_chain` make; Numba compiles calls to
the functions a closure holds as it does to named ones), so no list of kinds is kept here, and a
code no kind declares stops the run with an error instead of holding the valves. A law returns a
mode (or, for a valve that takes one, a continuous command in -1..1); :func:`command_valve` turns
it into the muscle's two valve-vector entries through its valve type's view
(:func:`frogsim.circuit.valves.valve_openings`) and :func:`command_openings` queues them due one
dead time later, kept with their due times in ``cs``; :func:`next_control_time` returns the earliest of the next sample and
the due times, and :func:`apply_due` writes a command into u when its time has come.
"""
from __future__ import annotations

import math

import numpy as np

from frogsim._jit import jit, jit_alloc, jit_inner, jit_step
from frogsim.circuit.layout import M_VALVE, VALVE_CHARGE, VALVE_VENT, VALVE_WIDTH, pressure_index, valve_index
from frogsim.circuit.valves import valve_openings
from frogsim.control import kinds
from frogsim.control.signals import (  # noqa: F401  (the memory layout and signals, re-exported)
    B_A_FILT, B_A_FILT_ON, B_A_SENSED, B_ANGLE, B_CLIPS, B_CMD_C, B_CMD_D, B_FILT, B_FILT_ON, B_INT, B_MODE,
    B_OMEGA, B_PHASE, B_PULSE, B_QC_HEAD, B_QC_N, B_QD_HEAD, B_QD_N, B_SENSED, B_SP, B_SW_C, B_SW_D,
    B_TARGET, B_VALVE, B_W_FILT, B_W_SENSED, CS_BLOCK, CS_DT, CS_FW, CS_PUMP, CS_Q, CS_SAMPLE, MODE_CHARGE,
    MODE_HOLD, MODE_VENT, TOL, B_FAULT_A, B_FAULT_P, B_FW0, FW_MEM, adc_count, fw_fault, pump_band, sense,
    sense_joint, sensor_noise, setpoint, block_size, controller_state_size, law_block, queue_due, queue_start)
from frogsim.control.table import (  # noqa: F401  (the table's layout, re-exported)
    KIND_EXTERNAL, KIND_PUMP_BAND, L_AADC_FULL, L_AADC_K, L_AADC_Q0, L_AADC_V0, L_ADC_FULL, L_ADC_K, L_ADC_Q0,
    L_ADC_V0, L_ADC_VREF, L_DEAD_C, L_DEAD_D, L_FAULT_AHI, L_FAULT_ALO, L_FAULT_MODE, L_FAULT_N, L_FAULT_PHI,
    L_FAULT_PLO, L_FW, L_HIGH, L_INJ_A_AT, L_INJ_A_COUNT, L_INJ_P_AT, L_INJ_P_COUNT, L_INPUT, L_JOINT1, L_KIND,
    L_LOW, L_MUSCLE, L_PATM, L_SIZE, laws_table)


def sampled_laws(g):
    """The laws of a run without closed-loop controllers: the pump's band as a 1-D row (columns
    L_*; an empty row when the pump is off), as :func:`frogsim.control.table.laws_table` makes it.
    A 1-D table is the open-loop form: the functions below take their ``laws.ndim == 1`` branch,
    which Numba compiles alone, so open-loop runs never compile the closed-loop laws."""
    return laws_table(g, [])


@jit
def observe_joints(laws, cs, qpos, qvel, leg_qpos, leg_dof):
    """Write each joint-angle row's observation into its memory: the angle qpos[leg_qpos[j]] and
    velocity qvel[leg_dof[j]] of its joint j (the coupled engine calls this before advancing the
    pneumatics over a step, so a sample in that step reads the state at the step's start)."""
    if laws.ndim == 1:
        return
    for c in range(laws.shape[0]):
        j = int(laws[c, L_JOINT1]) - 1
        if j < 0 or not _is_valve_law(laws[c, L_KIND]):
            continue
        b = _block(cs, c)
        cs[b + B_ANGLE] = qpos[leg_qpos[j]]
        cs[b + B_OMEGA] = qvel[leg_dof[j]]


# --- commands, their dead time and the driver's protocol ------------------------------------------------
@jit_step
def _block(cs, c):
    return law_block(cs, c)


@jit_step
def _push(cs, b, head, q0, due, state):
    Q = int(cs[CS_Q])
    n = int(cs[b + head + 1])
    j = (int(cs[b + head]) + n) % Q
    e = b + queue_due(q0, j)
    cs[e] = due
    cs[e + 1] = state
    cs[b + head + 1] = n + 1


@jit
def command_openings(laws, c, cs, want_c, want_d, ts, mode):
    """Law c sets its muscle's two valve-vector entries to ``want_c`` (charge path) and ``want_d``
    (discharge path) at sample time ts: each entry whose value changes gets a queued command due
    one dead time later (a switching valve's entries are 0 or 1, a proportional valve's its
    edges' openings, :mod:`frogsim.circuit.valves`). A path's opening never comes due before the
    other path's closing (with unequal dead times both are never open together)."""
    b = _block(cs, c)
    Q = int(cs[CS_Q])
    close_c = -math.inf
    close_d = -math.inf
    if want_c < cs[b + B_CMD_C]:
        close_c = ts + laws[c, L_DEAD_C]
        _push(cs, b, B_QC_HEAD, queue_start(VALVE_CHARGE, Q), close_c, want_c)
        cs[b + B_CMD_C] = want_c
    if want_d < cs[b + B_CMD_D]:
        close_d = ts + laws[c, L_DEAD_D]
        _push(cs, b, B_QD_HEAD, queue_start(VALVE_VENT, Q), close_d, want_d)
        cs[b + B_CMD_D] = want_d
    if want_c > cs[b + B_CMD_C]:
        _push(cs, b, B_QC_HEAD, queue_start(VALVE_CHARGE, Q), max(ts + laws[c, L_DEAD_C], close_d), want_c)
        cs[b + B_CMD_C] = want_c
    if want_d > cs[b + B_CMD_D]:
        _push(cs, b, B_QD_HEAD, queue_start(VALVE_VENT, Q), max(ts + laws[c, L_DEAD_D], close_c), want_d)
        cs[b + B_CMD_D] = want_d
    cs[b + B_MODE] = mode


@jit
def command_valves(laws, c, cs, mode, ts):
    """Law c commands ``mode`` at sample time ts, open-or-shut: charge opens the charge path
    (entry 1) with the discharge path shut, vent the other way round, hold shuts both (the
    commands of a Python controller function, whatever the valve type: a proportional valve's
    edges then open fully at once)."""
    command_openings(laws, c, cs, 1.0 if mode > 0 else 0.0, 1.0 if mode < 0 else 0.0, ts, mode)


@jit
def command_valve(laws, mp, c, cs, b, i, command, ts):
    """Law c's command at sample time ts (a mode, or a continuous command in -1..1) through the
    controllers' view of muscle i's valve type (:func:`frogsim.circuit.valves.valve_openings`:
    the valve-vector entries over the next period and the valve's memory, kept at B_VALVE)."""
    want_c, want_d, memory = valve_openings(mp[i, M_VALVE], mp, i, command, cs[b + B_VALVE], cs[CS_DT])
    cs[b + B_VALVE] = memory
    command_openings(laws, c, cs, want_c, want_d, ts, command)


@jit
def _is_valve_law(kind):
    """Every row but the pump's band (and an empty row) drives a muscle's valves."""
    return kind != KIND_PUMP_BAND and kind != 0.0


@jit
def apply_due(laws, t, u, cs):
    """Write into u every queued valve command due at or before t; True if a valve changed."""
    if laws.ndim == 1:                     # open loop: no valve laws, no command queue
        return False
    changed = False
    Q = int(cs[CS_Q])
    for c in range(laws.shape[0]):
        if not _is_valve_law(laws[c, L_KIND]):
            continue
        b = _block(cs, c)
        i = int(laws[c, L_MUSCLE])
        for valve in range(VALVE_WIDTH):          # VALVE_CHARGE, then VALVE_VENT
            head = B_QC_HEAD if valve == VALVE_CHARGE else B_QD_HEAD
            q0 = queue_start(valve, Q)
            while cs[b + head + 1] > 0:
                h = int(cs[b + head])
                e = b + queue_due(q0, h)
                if cs[e] > t + TOL:
                    break
                state = cs[e + 1]
                j = valve_index(i, valve)
                if u[j] != state:
                    u[j] = state
                    cs[b + B_SW_C + valve] += 1.0
                    changed = True
                cs[b + head] = float((h + 1) % Q)
                cs[b + head + 1] -= 1.0
    return changed


@jit
def next_control_time(laws, cs, ctrl_dt):
    """The next time [s] at which the controllers need the integrator to stop (inf if never): the
    next sample, or a queued valve command's due time if earlier."""
    return min(next_sample_time(laws, cs), next_due_time(laws, cs))


@jit_step
def next_sample_time(laws, cs):
    """The time [s] of the controllers' next sample (inf when the run has no sampled rule)."""
    if laws.ndim == 1:
        return (cs[CS_SAMPLE] + 1.0) * cs[CS_DT] if laws.size else math.inf
    if laws.shape[0] == 0:
        return math.inf
    return (cs[CS_SAMPLE] + 1.0) * cs[CS_DT]


@jit_step
def next_due_time(laws, cs):
    """The earliest due time [s] of the valve commands waiting in the queues (inf if none): the
    times at which a valve's state will change, known since the sample that decided it. A due
    time within TOL of a sample time k dt (a dead time that is a whole number of periods, summed
    in floating point) is that sample time when the sample is earlier: the command acts there, as
    :func:`apply_due` (tolerance TOL) applies it at that sample."""
    t = math.inf
    if laws.ndim == 1:
        return t
    Q = int(cs[CS_Q])
    for c in range(laws.shape[0]):
        if not _is_valve_law(laws[c, L_KIND]):
            continue
        b = _block(cs, c)
        if cs[b + B_QC_N] > 0:
            t = min(t, cs[b + queue_due(queue_start(VALVE_CHARGE, Q), int(cs[b + B_QC_HEAD]))])
        if cs[b + B_QD_N] > 0:
            t = min(t, cs[b + queue_due(queue_start(VALVE_VENT, Q), int(cs[b + B_QD_HEAD]))])
    if t < math.inf:
        dt = cs[CS_DT]
        ts = math.floor(t / dt + 0.5) * dt
        if ts < t and t - ts <= TOL:
            t = ts
    return t


@jit
def sample_controllers(laws, mp, t, y, u, cs):
    """At a stop t: write the valve commands that have come due into u; if t is the next sample,
    take it: evaluate every law on the state y and write or queue its commands (the pump's switch
    cs[CS_PUMP] at once, valve commands one dead time later). ``mp`` is the model's muscle rows,
    where a law that models the valves reads their ISO 6358 constants (the table holds none).
    True if a command changed.

    A row with a firmware block runs its law's integer twin (:func:`firmware_mode`) only in a run
    whose firmware switch cs[CS_FW] is on (set by :func:`start_controllers`): a float run tests
    the switch once a sample, not each row's L_FW."""
    if laws.ndim == 1:                     # open loop (see sampled_laws): the pump's band only
        if t < (cs[CS_SAMPLE] + 1.0) * cs[CS_DT] - TOL:
            return False
        cs[CS_SAMPLE] += 1.0
        if laws.size == 0:
            return False
        on = pump_band(y[int(laws[L_INPUT])], cs[CS_PUMP], laws[L_LOW], laws[L_HIGH])
        if on != cs[CS_PUMP]:
            cs[CS_PUMP] = on
            return True
        return False
    changed = apply_due(laws, t, u, cs)
    dt = cs[CS_DT]
    if t < (cs[CS_SAMPLE] + 1.0) * dt - TOL:
        return changed              # a due time between samples
    cs[CS_SAMPLE] += 1.0
    k = int(cs[CS_SAMPLE])
    ts = cs[CS_SAMPLE] * dt
    firmware = cs[CS_FW] > 0.0
    valves = False
    for c in range(laws.shape[0]):
        kind = laws[c, L_KIND]
        if kind == KIND_PUMP_BAND:
            on = pump_band(y[int(laws[c, L_INPUT])], cs[CS_PUMP], laws[c, L_LOW], laws[c, L_HIGH])
            if on != cs[CS_PUMP]:
                cs[CS_PUMP] = on
                changed = True
            continue
        if not _is_valve_law(kind):
            continue
        valves = True
        b = _block(cs, c)
        i = int(laws[c, L_MUSCLE])
        if firmware and laws[c, L_FW] > 0.0 and kind != KIND_EXTERNAL:
            # [firmware]: the law's integer twin on the ADC's counts (frogsim.control.fixed)
            command_valve(laws, mp, c, cs, b, i, firmware_mode(laws, c, cs, b, y, k, ts), ts)
            continue
        p = sense(laws, c, y[pressure_index(i)], cs, b, k, dt)
        cs[b + B_SENSED] = p
        if kind == KIND_EXTERNAL:
            if laws[c, L_JOINT1] > 0.0:
                sense_joint(laws, c, cs, b, k, dt)
            continue                # commanded from Python (command_valves)
        # the kind's law, by its code (the registry's dispatch, law_mode)
        command_valve(laws, mp, c, cs, b, i, law_mode(kind, laws, mp, c, cs, b, y, p, ts), ts)
    if valves and apply_due(laws, t, u, cs):       # commands without dead time act at once
        changed = True
    return changed


@jit
def count_value(v0, kv, q0, full, vref, count):
    """The reading [Pa gauge or rad] in the middle of an ADC count (the inverse of
    :func:`frogsim.control.signals.adc_count` at count + 1/2)."""
    return q0 + ((count + 0.5) * vref / full - v0) / kv


@jit
def firmware_mode(laws, c, cs, b, y, k, ts):
    """Law c's mode at sample k in firmware mode: its muscle's pressure (and its joint's angle,
    observed in cs) converted to ADC counts, then its kind's integer twin (``fw_law`` of its
    module) on its firmware block (parameters P, table T) and its memory cs[b + B_FW0:]. What
    the model reports is written as the float law writes it: the sensed pressure and angle (the
    counts' middles), the setpoint at ts, the clipped samples."""
    kind = laws[c, L_KIND]
    i = int(laws[c, L_MUSCLE])
    patm = laws[c, L_PATM]
    full = laws[c, L_ADC_FULL]
    vref = laws[c, L_ADC_VREF]
    cp = adc_count(laws[c, L_ADC_V0], laws[c, L_ADC_K], laws[c, L_ADC_Q0], full, vref, y[pressure_index(i)] - patm)
    if ts >= laws[c, L_INJ_P_AT]:                      # a fault put into the plant: the wire's count
        cp = int(laws[c, L_INJ_P_COUNT])
    cs[b + B_SENSED] = patm + count_value(laws[c, L_ADC_V0], laws[c, L_ADC_K], laws[c, L_ADC_Q0], full, vref, cp)
    ca = 0
    if laws[c, L_JOINT1] > 0.0:
        afull = laws[c, L_AADC_FULL]
        ca = adc_count(laws[c, L_AADC_V0], laws[c, L_AADC_K], laws[c, L_AADC_Q0], afull, vref, cs[b + B_ANGLE])
        if ts >= laws[c, L_INJ_A_AT]:
            ca = int(laws[c, L_INJ_A_COUNT])
        cs[b + B_A_SENSED] = count_value(laws[c, L_AADC_V0], laws[c, L_AADC_K], laws[c, L_AADC_Q0], afull, vref,
                                         ca)
    sp, _ = setpoint(laws, c, ts)
    cs[b + B_SP] = sp
    # the channels' fault checks (both evaluated: each counts its good samples), then the law
    fault = False
    if laws[c, L_FAULT_PLO] >= 0.0:
        fault = fw_fault(cp, laws[c, L_FAULT_PLO], laws[c, L_FAULT_PHI], cs, b + B_FAULT_P, laws[c, L_FAULT_N])
    if laws[c, L_FAULT_ALO] >= 0.0:
        if fw_fault(ca, laws[c, L_FAULT_ALO], laws[c, L_FAULT_AHI], cs, b + B_FAULT_A, laws[c, L_FAULT_N]):
            fault = True
    if fault:
        return laws[c, L_FAULT_MODE]
    at = int(laws[c, L_FW])
    n_p = int(laws[c, at])
    n_t = int(laws[c, at + 1])
    P = laws[c, at + 2:at + 2 + n_p]
    T = laws[c, at + 2 + n_p:at + 2 + n_p + n_t]
    mem = cs[b + B_FW0:b + B_FW0 + FW_MEM]
    mode = fw_dispatch(kind, P, T, mem, k, cp, ca)
    fw_report(kind, cs, b, mem)
    return float(mode)


# --- the kinds' dispatch, assembled from the registry (frogsim.control.kinds) ----------------------------
def _law_chain(entries):
    """``law_mode(kind, laws, mp, c, cs, b, y, p, ts) -> mode``: the law of the kind whose code is
    ``kind`` (``entries``: the kinds with a law, at least one), one compiled branch per kind, each
    a closure that tries its code and hands on to the next; the last raises ValueError for a code
    that is not its own."""
    def last(code, law):
        @jit_inner
        def branch(kind, laws, mp, c, cs, b, y, p, ts):
            if kind != code:
                raise ValueError("sample_controllers: a row of the table of laws has a kind code that no "
                                 "controller kind declares (frogsim.control.kinds)")
            return law(laws, mp, c, cs, b, y, p, ts)
        return branch

    def link(code, law, rest):
        @jit_inner
        def branch(kind, laws, mp, c, cs, b, y, p, ts):
            if kind == code:
                return law(laws, mp, c, cs, b, y, p, ts)
            return rest(kind, laws, mp, c, cs, b, y, p, ts)
        return branch

    out = last(entries[-1].code, entries[-1].law)
    for k in reversed(entries[:-1]):
        out = link(k.code, k.law, out)
    return out


def _twin_chain(entries):
    """``fw_dispatch(kind, P, T, mem, k, cp, ca) -> mode``: the firmware twin (``fw_law``) of
    the kind whose code is ``kind``, as :func:`_law_chain` builds the laws' dispatch (the last
    raises ValueError for a code that is not its own)."""
    def last(code, fw_law):
        @jit_inner
        def branch(kind, P, T, mem, k, cp, ca):
            if kind != code:
                raise ValueError("fw_dispatch: a firmware block's kind code is no controller kind's with a "
                                 "firmware twin (frogsim.control.kinds)")
            return fw_law(P, T, mem, k, cp, ca)
        return branch

    def link(code, fw_law, rest):
        @jit_inner
        def branch(kind, P, T, mem, k, cp, ca):
            if kind == code:
                return fw_law(P, T, mem, k, cp, ca)
            return rest(kind, P, T, mem, k, cp, ca)
        return branch

    out = last(entries[-1].code, entries[-1].firmware.fw_law)
    for kd in reversed(entries[:-1]):
        out = link(kd.code, kd.firmware.fw_law, out)
    return out


def _report_chain(entries):
    """``fw_report(kind, cs, b, mem)``: the twin's ``report`` of the kind whose code is ``kind``
    (``entries``: the kinds whose twin has one); nothing for the others."""
    @jit_inner
    def none(kind, cs, b, mem):
        return

    def link(code, report, rest):
        @jit_inner
        def branch(kind, cs, b, mem):
            if kind == code:
                report(cs, b, mem)
            else:
                rest(kind, cs, b, mem)
        return branch

    out = none
    for kd in reversed(entries):
        out = link(kd.code, kd.firmware.report, out)
    return out


#: the law of a row's kind (every kind with rows)
law_mode = _law_chain(kinds.with_law())
#: the integer twin's law of a firmware block's kind: the one dispatch the model's compiled sample
#: and the firmware plan's twin (:func:`frogsim.control.firmware.firmware_modes`) share
fw_dispatch = _twin_chain([k for k in kinds.with_twin() if k.code is not None])
#: what a twin leaves in its memory for the results, copied into the row's block after its sample
fw_report = _report_chain([k for k in kinds.with_twin() if k.code is not None and k.firmware.report is not None])


@jit_alloc
def start_controllers(laws, mp, t0, y, u, ctrl_dt):
    """Controller state at the start of a run at t0: pump stopped, valves under control shut, the
    firmware switch cs[CS_FW] on when some row of the table has a firmware block, then the sample
    at or just before t0 taken (its commands hold from t0 on, or a dead time later); ``mp`` as
    :func:`sample_controllers` takes it."""
    if laws.ndim == 1:                     # open loop: no valve laws, no command queue
        cs = np.zeros(controller_state_size(0, 0))
        cs[CS_DT] = ctrl_dt
        cs[CS_SAMPLE] = math.floor(t0 / ctrl_dt + 1e-9) - 1.0
        sample_controllers(laws, mp, t0, y, u, cs)
        return cs
    dead = 0.0
    for c in range(laws.shape[0]):
        if _is_valve_law(laws[c, L_KIND]):
            dead = max(dead, laws[c, L_DEAD_C], laws[c, L_DEAD_D])
    Q = int(math.ceil(dead / ctrl_dt)) + 3
    block = block_size(Q)
    cs = np.zeros(controller_state_size(laws.shape[0], block))
    cs[CS_DT] = ctrl_dt
    cs[CS_BLOCK] = block
    cs[CS_Q] = Q
    for c in range(laws.shape[0]):
        if laws[c, L_FW] > 0.0:
            cs[CS_FW] = 1.0
    cs[CS_SAMPLE] = math.floor(t0 / ctrl_dt + 1e-9) - 1.0
    sample_controllers(laws, mp, t0, y, u, cs)
    return cs


def switch_counts(laws, cs) -> dict:
    """{law row c: (charge valve switchings, discharge valve switchings)} of the valve laws."""
    out = {}
    if laws.ndim == 1:
        return out
    for c in range(laws.shape[0]):
        if _is_valve_law(laws[c, L_KIND]):
            b = law_block(cs, c)
            out[c] = (int(cs[b + B_SW_C]), int(cs[b + B_SW_D]))
    return out


_MODES = {"charge": MODE_CHARGE, "hold": MODE_HOLD, "vent": MODE_VENT,
          1: MODE_CHARGE, 0: MODE_HOLD, -1: MODE_VENT}


def command_from_python(laws, rows: dict, cs, cmds, t_k: float, u, t_now: float) -> None:
    """A Python controller function's commands at sample t_k, {muscle: "charge" | "hold" | "vent"
    (or +1, 0, -1)}, checked and queued like a compiled law's (:func:`command_valves`; ``rows``:
    muscle -> its law row); commands without dead time act at once (written into u at t_now).

    ``cmds`` may also be a list of (t, muscle, mode) in time order: commands issued between
    samples, each queued at its own time t, which may lie before t_k by less than the valves' dead
    time (software in the loop: the firmware's pin writes at the cycle it made them, its plant a
    period ahead with encoders, :mod:`frogsim.export.sil`)."""
    from frogsim.errors import SimulationError
    timed = cmds if isinstance(cmds, list) else [(t_k, n, m) for n, m in (cmds or {}).items()]
    for t, name, mode in timed:
        if name not in rows:
            raise SimulationError(f"controller function: muscle {name!r} is not free for closed-loop "
                                  f"control (free: {', '.join(rows) or 'none'})")
        if mode not in _MODES:
            raise SimulationError(f"controller function: mode {mode!r} for {name!r} must be "
                                  "'charge', 'hold' or 'vent'")
        c = rows[name]
        if not t + min(laws[c, L_DEAD_C], laws[c, L_DEAD_D]) >= t_now - TOL:
            raise SimulationError(f"controller function: a command for {name!r} issued at t = {t!r} s would act "
                                  f"before now ({t_now:g} s): a command may be issued before the sample only "
                                  "by less than the valves' dead time")
        b = law_block(cs, rows[name])
        if max(cs[b + B_QC_N], cs[b + B_QD_N]) >= cs[CS_Q] - 1:
            raise SimulationError(f"controller function: more valve commands for {name!r} within one dead time "
                                  f"than its queue holds ({int(cs[CS_Q])}) at t = {t:g} s")
        command_valves(laws, c, cs, _MODES[mode], float(t))
    apply_due(laws, t_now, u, cs)
