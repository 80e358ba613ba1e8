"""What an integration method's module declares (not a method: it declares none).

Every method module of :mod:`frogsim.engine.methods` ends with one declaration,
``METHOD = IntegrationMethod(...)``, which the registry (:mod:`frogsim.engine.methods`) finds and
checks when the package is imported. It names, in one place, everything the driver
(:func:`frogsim.engine.integrator.advance`) reads of the method:

* ``settings``: its settings class (a frozen dataclass derived from
  :class:`frogsim.scenario.methods.MethodSettings`; its ``METHOD`` is the method's name in files,
  its fields the settings a file may write, its ``params()`` the parameter block its compiled
  functions read, its ``check`` its cross-field checks);
* ``code``: the float that selects it in the driver's dispatch (the first entry of the parameter
  block, ``par[0]``), unique among the methods;
* ``step``: its compiled step (Numba, :func:`frogsim._jit.jit_inner` or ``jit_step``; every part
  takes the arguments :data:`PART_ARGS` lists, in that order, which the registry checks)::

      step(t, h, t_new, y, f, yn, fn, u, pump_on, model, atol, rtol, par, ds, own, rc, mat,
           kmat, kvec, aux, work, stats) -> (err, a1, a2, dense_ready)

  one step from (t, y), dy/dt = f, to t_new = t + h (t_new passed so that a step ending a piece
  ends on it exactly): the solution into ``yn``, dy/dt at (t_new, yn) into ``fn`` (the next
  step's f), and its error estimate ``err`` (the weighted RMS norm, 1 = the tolerance; 0 for a
  method without one, inf or NaN for a step that failed); ``a1``, ``a2`` are two numbers the
  method hands to its own ``accepted`` control (the default: its stiffness test's norms),
  ``dense_ready`` True when the step has also written its continuous extension into ``rc``
  (the driver's four vectors rc1..rc4, see ``dense``). ``model`` is the right-hand side's group
  (:func:`frogsim.circuit.rhs.rhs`); ``par`` the parameter block; ``ds`` the driver state (the
  method's memory in its columns D_M0.., laid out below); ``own`` the method's
  scratch vectors, a tuple of ROWS - R_OWN vectors of ny entries cut once a call (index it with
  constants; ``vectors`` of them are the method's), ``mat`` a scratch ny x ny matrix, ``kmat``
  (ny x ny) and ``kvec`` (ny) entries kept from call to call (the default's Jacobian and df/dt);
  ``aux``, ``work`` the right-hand side's scratch; ``stats`` the step counters (stats[2]:
  right-hand-side evaluations, which the method counts);
* ``dense``: its continuous extension, made after the step when a sample or an output row falls
  inside it: ``dense(h, y, yn, f, fn, own, rc1, rc2, rc3, rc4)`` writes coefficients such that
  ``y(t + th h) = y + th (rc1 + (1-th) (rc2 + th (rc3 + (1-th) rc4)))`` (Hairer's DOPRI5 form;
  rc4 = 0 is the cubic Hermite interpolant of y, yn, f, fn);
* ``control``: its step-size control (:class:`StepControl`, :mod:`frogsim.engine.stepsize`);
* ``order``: its order of convergence (global error O(h^order)), which its tests check;
* ``vectors``: how many of the scratch vectors from R_OWN on it uses;
* ``warm``: optional, the parts of a first run's compilation its compiled functions make
  (:mod:`frogsim.engine.warmup`): ``warm(a) -> [(part, needs, what, [(function, arguments)])]``,
  ``a`` a dict of arguments of the types the driver passes (the step's parameter names: "t", "h",
  "y", "f", "u", "pump_on", "model", "atol", "rtol", "par", "ds", "vec", "mat", "keep", "aux",
  "work", "stats"), ``needs`` the names of its own parts, or "rhs", compiled first. Without it a
  step compiled on its own (``jit_step``) is one part, compiled for the step's arguments; an
  inlined step (``jit_inner``) is compiled with the driver. The other members compiled on their
  own (continuous extension, step-size control, restart) make one more part, ``controls``,
  compiled for the arguments :data:`PART_ARGS` lists.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

# --- the scratch vectors vec[ROWS, ny] the driver hands every method ---------------------------------------
R_F = 0          # dy/dt at (t, y) (the driver's; the step reads it as f)
R_FN = 1         # dy/dt at (t_new, yn), written by the step
R_YN = 2         # the step's solution at t_new, written by the step
R_RC1, R_RC2, R_RC3, R_RC4 = 3, 4, 5, 6     # the step's continuous extension (see dense)
R_YS = 7         # the state at a sample inside the step (the driver's)
R_OWN = 8        # the first row a method may use for its own stages
ROWS = 22        # rows in all: R_OWN + 14 of the method's own
# --- the driver state ds[:] (frogsim.engine.integrator.advance): the driver's columns and, between them, the
# columns a method may keep its memory in; then the method's kept entries, the kept dy/dt and the scratch
# (integrator.ds_size)
D_T = 0          # time reached [s]
D_H = 1          # next trial step [s]
D_ERR = 2        # the step-size control's memory: error norm of the last accepted step
D_SI = 3         # index of the next valve-schedule entry
D_OUT = 4        # next output row
D_PAUSE = 5      # > 0: pause once this many steps are accepted in all (stats[0]); 0: never
D_M0 = 6         # the first of the method's memory columns
D_M_COUNT = 6    # how many
D_F_VALID = 12   # 1: dy/dt at (ds[D_T], y) is kept after the method's entries (written by every call that ends well)
D_REUSE_F = 13   # 1: the caller changed nothing that dy/dt reads since the last call: start from the kept one
D_SIZE = 14
STATS_SIZE = 4   # stats[:]: accepted steps, rejected steps, rhs evaluations, accepted Rosenbrock steps
assert D_M0 == D_PAUSE + 1 and D_M0 + D_M_COUNT == D_F_VALID     # the method's columns between the driver's

#: the arguments the driver passes each of a method's compiled parts, in order (the one list: the
#: driver's dispatch is generated from it, and the registry refuses a part that takes another
#: number of arguments). ``fn_`` is the step's ``fn`` (the dispatch's own closure holds a ``fn``).
PART_ARGS = {
    "step": "t, h, t_new, y, f, yn, fn_, u, pump_on, model, atol, rtol, par, ds, own, rc, mat, kmat, kvec, aux, "
            "work, stats",
    "dense": "h, y, yn, f, fn_, own, rc1, rc2, rc3, rc4",
    "propose": "par, t, t_seg, h, max_step",
    "accepted": "ds, par, h, err, err_old, a1, a2, refresh, stats",
    "rejected": "ds, par, h, err",
    "restart": "ds",
}
#: entries of a method's parameter block ``par``: its code, then its settings' params()
PAR_SIZE = 4


@dataclass(frozen=True)
class StepControl:
    """A step-size control (:mod:`frogsim.engine.stepsize`), three compiled functions:

    * ``propose(par, t, t_seg, h, max_step) -> (h, h_try, t_new, last)``: the next trial step
      from t, ending at t_seg at the latest (h the carried step size, returned as the control
      holds it: the adaptive one at most max_step);
    * ``accepted(ds, par, h, err, err_old, a1, a2, refresh, stats) -> (h_next, err_old)``: after
      an accepted step of length h with error norm err (err_old the previous one's; ``refresh``
      when a controller's command changed in the step);
    * ``rejected(ds, par, h, err) -> h``: after a rejected or non-finite step; a step below
      1e-14 s stops the run."""
    propose: Callable
    accepted: Callable
    rejected: Callable


@dataclass(frozen=True, kw_only=True)
class IntegrationMethod:
    """A method's declaration (module docstring). ``restart(ds)``, optional, is called when the
    commands change at a piece's end (the right-hand side jumps): the default method goes back to
    its explicit steps there. ``module`` is filled in by the registry."""
    settings: type
    code: float
    step: Callable
    dense: Callable
    control: StepControl
    order: int
    vectors: int
    restart: Callable | None = None
    warm: Callable | None = None
    module: str = ""

    @property
    def name(self) -> str:
        """The method's name in files (its settings class's ``METHOD``)."""
        return self.settings.METHOD

    def registered(self, module: str) -> "IntegrationMethod":
        return dataclasses.replace(self, module=module)

    def block(self, settings) -> "list[float]":
        """The parameter block of ``settings`` (this method's): [code, *settings.params()]."""
        return [self.code, *(float(v) for v in settings.params())]
