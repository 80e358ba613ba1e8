"""Sampled controllers: valve and pump commands decided from the state at the controller's samples.

The controller samples the circuit at t_k = k ctrl_dt (ctrl_dt = 1 / rate: 1 ms at the paper's
1 kHz) and sets commands that hold until it changes them: the valves' states u (1 open, 0 shut)
and the pump's switch. Two sorts of controller give them:

* open-loop programs (the scenario's programs, the gait). Their commands are known before the run,
  so they are not evaluated while it runs: :func:`frogsim.circuit.model.build_schedule` turns them
  into the schedule (sched_t, sched_u) of the times at which the valves change (the sample that
  issues a command plus the valve's dead time), and the driver
  (:func:`frogsim.engine.integrator.advance`) applies it;
* sampled rules (this module): evaluated at every sample from the state at that instant. Today one:
  the pump's pressure band (:func:`pump_band`), a hysteresis (bang-bang) switch on the source
  pressure that acts at once (the pump's motor has no dead time in the model).

A run's sampled rules are the rows of a table ``laws[c, :]`` (a kind and its parameters, columns
L_*), built by :func:`sampled_laws`; their memory (and the pump's switch) is a small array ``cs``
(columns CS_*) made by :func:`start_controllers`. The driver knows only three functions:
:func:`start_controllers` (once, at the start of a run), :func:`next_control_time` (where it has
to stop next for the controllers) and :func:`sample_controllers` (called there; returns True when a
command changed, so that the driver evaluates the right-hand side again).

Adding a closed-loop rule (bang-bang or PWM on a muscle pressure, sliding mode, ...) touches this
module only: a KIND_* constant and its parameter columns, the law as a small compiled function of
(parameters, t, y, u), a branch in :func:`sample_controllers` that writes its commands, and its row
in :func:`sampled_laws`. A rule that commands a valve must respect the valve's dead time: it keeps
the command with its due time (decision time + dead time) in ``cs`` (make ``cs`` longer in
:func:`start_controllers`), :func:`next_control_time` returns the earliest of the next sample and
the due times, and :func:`sample_controllers` writes a command into u when its time has come.
"""
from __future__ import annotations

import math

import numpy as np

from frogsim._jit import jit
from frogsim.circuit.layout import G_PUMP_ENABLED, G_PUMP_OFF, G_PUMP_ON, Y_PS

# --- kinds of sampled rule ---------------------------------------------------------------------------
KIND_PUMP_BAND = 1.0

# --- rule table laws[c, :] -----------------------------------------------------------------------------
L_KIND = 0       # KIND_*
L_INPUT = 1      # index of the state entry the rule reads (e.g. Y_PS)
L_LOW = 2        # band: switch on below this value
L_HIGH = 3       # band: switch off above this value
L_SIZE = 4

# --- controller state cs[:] ------------------------------------------------------------------------------
CS_SAMPLE = 0    # index k of the last sample taken
CS_PUMP = 1      # the pump's switch: 1 running, 0 stopped
CS_SIZE = 2


@jit
def sampled_laws(g):
    """The rule table of a circuit with constants g: the pump's band when the pump is enabled."""
    if g[G_PUMP_ENABLED] < 0.5:
        return np.zeros((0, L_SIZE))
    laws = np.zeros((1, L_SIZE))
    laws[0, L_KIND] = KIND_PUMP_BAND
    laws[0, L_INPUT] = Y_PS
    laws[0, L_LOW] = g[G_PUMP_ON]
    laws[0, L_HIGH] = g[G_PUMP_OFF]
    return laws


@jit
def pump_band(x, on, low, high):
    """Hysteresis switch: on (1) below ``low``, off (0) above ``high``, else unchanged (``on``).

    The pump's pressure band on the source pressure x [Pa abs]: it starts when the reservoir has
    fallen below the lower limit and stops when it is above the upper one.
    """
    if x < low:
        return 1.0
    if x > high:
        return 0.0
    return on


@jit
def next_control_time(laws, cs, ctrl_dt):
    """The next time [s] at which the controllers need the integrator to stop (inf if never)."""
    if laws.shape[0] == 0:
        return math.inf
    return (cs[CS_SAMPLE] + 1.0) * ctrl_dt


@jit
def sample_controllers(laws, t, y, u, cs):
    """Take the next sample at time t: evaluate every rule on the state y, write the commands
    (valve states u, the pump's switch cs[CS_PUMP]); True if one of them changed."""
    cs[CS_SAMPLE] += 1.0
    changed = False
    for c in range(laws.shape[0]):
        kind = laws[c, L_KIND]
        if kind == KIND_PUMP_BAND:
            on = pump_band(y[int(laws[c, L_INPUT])], cs[CS_PUMP], laws[c, L_LOW], laws[c, L_HIGH])
            if on != cs[CS_PUMP]:
                cs[CS_PUMP] = on
                changed = True
    return changed


@jit
def start_controllers(laws, t0, y, u, ctrl_dt):
    """Controller state at the start of a run at t0: pump stopped, then the sample at or just before
    t0 taken (its commands hold from t0 on)."""
    cs = np.zeros(CS_SIZE)
    cs[CS_SAMPLE] = math.floor(t0 / ctrl_dt + 1e-9) - 1.0
    sample_controllers(laws, t0, y, u, cs)
    return cs
