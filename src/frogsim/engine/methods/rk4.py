"""Integration method "rk4": the classical fourth-order Runge-Kutta method at a fixed step, for
real-time and co-simulation use (a run's cost known before it starts: four right-hand-side
evaluations a step, every step the same length, nothing rejected).

Method: Kutta (1901), as in Hairer, Norsett and Wanner, Solving ODEs I, Table II.1.2 (left):

    k1 = f(t, y),  k2 = f(t + h/2, y + h/2 k1),  k3 = f(t + h/2, y + h/2 k2),  k4 = f(t + h, y + h k3)
    y1 = y + h/6 (k1 + 2 k2 + 2 k3 + k4)

order 4 (global error O(h^4)); k1 is the previous step's f(t + h, y1), so a step costs four
evaluations. Its stability interval on the negative real axis is h |lambda| <= 2.785 (ibid.,
Sec. IV.2, Fig. 2.1): the step must stay below 2.785 / |lambda| of the circuit's fastest
eigenvalue, which docs/solver.md measures on the shipped scenarios.
Continuous extension: the cubic Hermite interpolant of y, y1, f(t, y) and f(t + h, y1) (order 3;
no extra evaluation), for the controllers' samples and the output rows inside a step.
No error estimate: the step is the user's choice (``step``), and the benchmark
(benchmarks/bench_solver_methods.py) measures its accuracy against the default method.

Steps lie on the grid k ``step`` from t = 0 (:func:`frogsim.engine.stepsize.propose_grid`), so
with a step that divides the controller period (the scenario is refused otherwise) every
controller sample is a step's end; a valve's switching time or a queued command's due time
between two grid points ends a shorter step there, and the next one goes on to the grid.

Settings: ``step`` [s] (written in ms, "0.1 ms"); ``rtol`` and ``max_step`` of ``[solver]`` are
the adaptive method's and are not read (``rtol`` still scales the state's absolute tolerances,
which this method does not use).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from frogsim._jit import jit_step
from frogsim.circuit.rhs import rhs
from frogsim.engine.methods.spec import IntegrationMethod, StepControl
from frogsim.engine.stepsize import accepted_fixed, propose_grid, rejected_fixed
from frogsim.errors import ScenarioError
from frogsim.scenario.fields import quantity, shown
from frogsim.scenario.methods import MethodSettings
from frogsim.scenario.motion import whole_steps

CODE = 2.0
#: the stability interval of the classical Runge-Kutta method on the negative real axis, h |lambda|
STABILITY_LIMIT = 2.785


@dataclass(frozen=True)
class Rk4Settings(MethodSettings):
    """The fixed step [s]: a whole fraction of the controller period (1 ms at 1 kHz: 1 ms, 0.5 ms,
    0.25 ms, 0.2 ms, 0.1 ms, ...)."""
    METHOD = "rk4"
    step: float = quantity("time", gt=0.0, le=0.1, display="ms", default=1e-4,
                           doc="the fixed step; a whole fraction of the controller period")

    def params(self) -> tuple:
        return (self.step,)

    def check(self, sc, path: str) -> None:
        """The step must divide the controller period a whole number of times, so that every
        controller sample is a step's end."""
        period = 1.0 / sc.controller.rate
        if whole_steps(period, self.step) is None:
            meta = next(f.metadata for f in self.__dataclass_fields__.values() if f.name == "step")
            raise ScenarioError(f"{path}.step", shown(self.step, meta),
                                f"must divide the controller period {period * 1e3:g} ms (controller.rate "
                                f"{sc.controller.rate:g} Hz) a whole number of times, e.g. "
                                f"{', '.join(f'{period * 1e3 / n:g} ms' for n in (1, 2, 4, 10))}")


@jit_step
def step(t, h, t_new, y, f, yn, fn, u, pump_on, model, atol, rtol, par, ds, own, rc, mat, kmat, kvec, aux, work, stats):
    """One classical Runge-Kutta step from (t, y), f = dy/dt there, to t_new = t + h: y1 into yn,
    f(t_new, y1) into fn (the next step's k1). Returns (err, 0, 0, False): err 0, or inf when y1
    is not finite (no error estimate; the continuous extension is made by :func:`dense`)."""
    g, mp, mot_t, mot_L, mot_d, mot_n = model
    k2, k3, k4, yt = own[0], own[1], own[2], own[3]
    ny = y.size
    half = 0.5 * h
    for j in range(ny):
        yt[j] = y[j] + half * f[j]
    rhs(t + half, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k2, aux, work)
    for j in range(ny):
        yt[j] = y[j] + half * k2[j]
    rhs(t + half, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k3, aux, work)
    for j in range(ny):
        yt[j] = y[j] + h * k3[j]
    rhs(t_new, yt, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, k4, aux, work)
    sixth = h / 6.0
    err = 0.0
    for j in range(ny):
        yn[j] = y[j] + sixth * (f[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if not math.isfinite(yn[j]):
            err = math.inf
    rhs(t_new, yn, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, fn, aux, work)
    stats[2] += 4
    return err, 0.0, 0.0, False


@jit_step
def dense(h, y, yn, f, fn, own, rc1, rc2, rc3, rc4):
    """The cubic Hermite interpolant of the step (y, yn and their slopes f, fn) in the driver's
    form: rc1 = yn - y, rc2 = h f - rc1, rc3 = rc1 - h fn - rc2, rc4 = 0."""
    for j in range(y.size):
        d = yn[j] - y[j]
        b = h * f[j] - d
        rc1[j] = d
        rc2[j] = b
        rc3[j] = d - h * fn[j] - b
        rc4[j] = 0.0


METHOD = IntegrationMethod(settings=Rk4Settings, code=CODE, step=step, dense=dense,
                           control=StepControl(propose=propose_grid, accepted=accepted_fixed,
                                               rejected=rejected_fixed),
                           order=4, vectors=4)
