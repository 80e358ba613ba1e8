"""Compiling the pneumatic engine in parts, so that two processes can share the first run's work.

Numba compiles a function together with everything it calls, so the engine is a chain: the
circuit's right-hand side, then the integration methods' compiled steps that call it, then the
stepping driver (:func:`frogsim.engine.integrator.advance`) over all of them. The dispatch
between the methods is inlined into the driver, and so is the default method's short step,
whose long pieces are compiled on their own; the methods' other members (continuous extension,
step-size control) are compiled on their own too, as parts of their own, so that they compile
beside the right-hand side rather than inside the driver's part. Each part is compiled once, for
the argument types the driver passes (a one-muscle circuit has the same types as any other), and
saved in the cache, where the next part, in this process or another, finds it. :data:`PARTS`
lists the parts with the parts each needs first; :func:`warm_up_parts` runs them on a process
pool, the driver's chain first (the longest: the manifold's flow, the right-hand side, the
steps, the driver), the parts that need nothing on the other process while it waits for the
chain, and what the driver does not need (a run's start, the measures, the physics a model's
build calls from Python) on the other process while the driver compiles.
"""
from __future__ import annotations

import numpy as np
from numba import typeof

from frogsim.circuit import actuators
from frogsim.circuit import layout as L
from frogsim.circuit.rhs import _hermite, common_piece, manifold_pressure, muscle_volume_state, rhs
from frogsim.engine import integrator as I
from frogsim.engine import methods
from frogsim.engine.methods.spec import PART_ARGS, R_OWN
from frogsim.engine.measures import _rises, _windows
from frogsim.physics.air import choked_mass_flux_factor, critical_pressure_ratio
from frogsim.physics.flow import main_pipe_branch_limit, tube_sonic_conductance
from frogsim.physics.muscle import braid_parameters

def _method_parts() -> list:
    """The integration methods' parts (:mod:`frogsim.engine.methods`), as (name, needs, what,
    calls): each method's ``warm`` (or its step as one part when it is compiled on its own), then
    its ``controls``: the rest of its members compiled on their own (continuous extension, step-size
    control, restart), which need nothing and so compile beside the right-hand side rather than
    inside the driver's part. A method's part names are prefixed with the method's
    ("dopri-rosenbrock:dopri"); a member shared by two methods is compiled once (the second
    finds it compiled)."""
    a = _one_muscle()
    out = []
    for m in methods.METHODS.values():
        if m.warm is not None:
            parts = list(m.warm(a))
        elif _own(m.step):
            parts = [("step", ("rhs",), f"the {m.name} step", [(m.step, _part_args(a, "step"))])]
        else:
            parts = []
        members = {"dense": m.dense, "propose": m.control.propose, "accepted": m.control.accepted,
                   "rejected": m.control.rejected, "restart": m.restart}
        calls = [(fn, _part_args(a, part)) for part, fn in members.items() if _own(fn)]
        if calls:
            parts.append(("controls", (), "its continuous extension and step-size control", calls))
        for name, needs, what, calls in parts:
            out.append((f"{m.name}:{name}", tuple(n if n == "rhs" else f"{m.name}:{n}" for n in needs),
                        f"{what} ({m.name})", calls))
    return out


def _own(fn) -> bool:
    """A method's member compiled on its own (``jit_step``), not inlined into the driver."""
    return hasattr(fn, "compile") and fn.targetoptions.get("inline") != "always"


def _part_args(a: dict, part: str) -> tuple:
    """The arguments the driver passes a method's ``part``, in the order
    :data:`frogsim.engine.methods.spec.PART_ARGS` lists them (the driver's names; "fn_" is fn)."""
    return tuple(a[name.strip().rstrip("_")] for name in PART_ARGS[part].split(","))


def _parts() -> tuple[dict, dict]:
    """(PARTS, the methods' calls by part name), in the order the processes take them: the
    right-hand side's chain (the manifold's flow, the volumes, the right-hand side), the methods'
    parts that need nothing (taken while the right-hand side compiles), the methods' parts that
    call the right-hand side, an accepted step's work, the driver, and last what the driver does
    not need, which compiles while it does."""
    found = _method_parts()
    parts = {
        "flow": ((), "the manifold pressure and the valves' flow (part of the right-hand side)"),
        "volume": ((), "the muscles' volumes along their length paths (part of the right-hand side)"),
        "rhs": (("flow", "volume"), "the circuit's right-hand side"),
    }
    # a method part that needs nothing first (the parts that need it come after it), then those
    # that need the right-hand side
    parts.update({name: (needs, what) for name, needs, what, _ in found if not needs})
    parts.update({name: (needs, what) for name, needs, what, _ in found if needs})
    parts["accept"] = ((), "an accepted step's work (samples, output rows, the continuous extension's evaluation)")
    parts["driver"] = (("rhs", "accept") + tuple(name for name, *_ in found), "the stepping driver")
    parts["start"] = ((), "a run's start")
    parts["measures"] = ((), "the rise-time measures")
    parts["model"] = ((), "the physics that building a model calls from Python (braid, tube, choked flow)")
    return parts, {name: calls for name, _, _, calls in found}


def _one_muscle():
    """Arguments of the types the driver passes, for a one-muscle circuit (values irrelevant)."""
    n = 1
    ny = L.state_size(n)
    a = {"ny": ny, "y": np.ones(ny), "f": np.zeros(ny), "u": np.zeros(L.valve_size(n)),
         "aux": np.zeros(L.flows_size(n)), "work": np.zeros(L.work_size(n)), "atol": np.ones(ny),
         "stats": np.zeros(I.STATS_SIZE, np.int64),
         "g": np.ones(L.G_SIZE), "mp": np.zeros((n, L.M_SIZE)), "mot_t": np.zeros((n, 1)), "mot_L": np.ones((n, 1)),
         "mot_d": np.zeros((n, 1)), "mot_n": np.ones(n, np.int64),
         # an open-loop run's commands, laws the pump's row (frogsim.control.sampled.sampled_laws)
         "sched_t": np.zeros(0), "sched_u": np.zeros((0, L.valve_size(n))), "laws": np.zeros(1), "ctrl_dt": 1e-3,
         "out_t": np.zeros(1), "out_y": np.zeros((1, ny)), "out_u": np.zeros((1, L.flows_size(n))),
         "ds": np.zeros(1), "cs": np.zeros(1)}
    # the driver's groups, in their orders (frogsim.circuit.layout)
    a["model"] = tuple(a[k] for k in L.MODEL_GROUP)
    a["commands"] = tuple(a[k] for k in L.COMMANDS_GROUP)
    a["out"] = tuple(a[k] for k in L.OUT_GROUP)
    a["dense"] = tuple(np.zeros(ny) for _ in range(4))
    a["vec"] = np.zeros((I.ROWS, ny))                          # the driver's scratch vectors
    a["par"] = methods.parameter_block(methods.METHODS[methods.DEFAULT].settings())
    # the rest of a method's step's arguments (frogsim.engine.methods.spec)
    a.update(t=0.0, h=1e-3, t_new=1e-3, yn=a["f"], fn=a["f"], pump_on=0.0, rtol=1e-7, mat=np.zeros((ny, ny)),
             own=tuple(a["vec"][k] for k in range(R_OWN, I.ROWS)), rc=a["dense"], kmat=np.zeros((ny, ny)),
             kvec=np.zeros(ny), t_seg=1e-3, max_step=1e-3, err=0.5, err_old=1e-4, a1=0.0, a2=0.0, refresh=False)
    a.update(zip(("rc1", "rc2", "rc3", "rc4"), a["dense"]))
    return a


# name: (the parts it needs compiled first, what it compiles), in the order the processes take them
# (warm_up_parts); the integration methods' parts come from their declarations (frogsim.engine.methods)
PARTS, _METHOD_CALLS = _parts()


def _compile(dispatcher, *args) -> None:
    """Compile (or load from the cache) ``dispatcher`` for the types of ``args``, without running it
    (nothing to do when NUMBA_DISABLE_JIT leaves it a plain Python function)."""
    if hasattr(dispatcher, "compile"):
        dispatcher.compile(tuple(typeof(x) for x in args))


def warm_up(part: str) -> None:
    """Compile (or load from the cache) one part of the engine (a key of :data:`PARTS`). Parts
    compiled in another process are loaded from the cache, so a part runs after those it needs."""
    a = _one_muscle()
    y, f, u, aux, work, atol, stats, model = (a[k] for k in ("y", "f", "u", "aux", "work", "atol", "stats",
                                                              "model"))
    g, mp, mot_t, mot_L, mot_d, mot_n = (a[k] for k in L.MODEL_GROUP)
    if part == "flow":
        _compile(manifold_pressure, 1e5, 293.0, y, u, g, mp, 1, work)
    elif part == "volume":
        _compile(muscle_volume_state, 0.0, 0, mp, mot_t, mot_L, mot_d, mot_n)
        _compile(common_piece, 0.0, mp, mot_t, mot_n)
        _compile(_hermite, 0.0, 0, 0, 1, mot_t, mot_L, mot_d)
    elif part == "rhs":
        _compile(rhs, 0.0, y, u, 0.0, *model, f, aux, work)
    elif part == "accept":
        _compile(I._accept, a["laws"], mp, a["cs"], 0.0, 1e-3, 1e-3, y, f, f, f, a["dense"], f, u, u,
                 0.0, a["out"], 0, stats)
        _compile(I._needs_dense, a["laws"], a["cs"], 1e-3, a["out_t"], 0)
        _compile(I._dense, y, *a["dense"], 0.5, f)
    elif part in _METHOD_CALLS:
        for function, arguments in _METHOD_CALLS[part]:
            _compile(function, *arguments)
    elif part == "driver":
        _compile(I.advance, 1.0, y, u, a["ds"], a["cs"], model, a["commands"], (1e-6, atol, 1e-3, a["par"]), a["out"],
                 stats)
    elif part == "start":
        _compile(I.begin, y, 0.0, u, mp, a["laws"], a["sched_t"], a["sched_u"], a["ctrl_dt"], a["out_t"], 1e-4)
    elif part == "measures":
        t, p = np.zeros(11), np.zeros((1, 11))
        _compile(_rises, t, p, p, p, np.zeros(1), 0.9)
        _compile(_windows, t, p, np.zeros(1))
    elif part == "model":
        _compile(braid_parameters, 0.15, 0.02, 0.5)
        for at in actuators.TYPES.values():         # a model's start volumes (frogsim.circuit.actuators)
            _compile(actuators.for_python(at.volume), a["model"][1], 0, 0.15)
        _compile(actuators.knot_volumes, a["model"][1], 0, a["model"][3], 1, np.zeros(1))
        _compile(critical_pressure_ratio, 1.4)
        _compile(choked_mass_flux_factor, 287.0, 1.4)
        _compile(main_pipe_branch_limit, 0.004, 10.0, 1, 1)
        _compile(tube_sonic_conductance, 0.004, 0.8, 287.0, 1.4, 293.0, 1.2)
    else:
        raise ValueError(f"unknown part {part!r}; the parts are {', '.join(PARTS)}")


def warm_up_parts(pool, workers: int) -> None:
    """Compile every part of :data:`PARTS` on ``pool`` (a process pool of ``workers`` processes): a
    free process takes the first part in the listed order whose needs are done (a part that
    needs nothing goes ahead of one still waiting for the right-hand side), except the parts
    listed after the driver, which wait until the driver is handed out (a long one taken early
    would hold a process the driver's chain needs next). Returns when all are done; a part's error
    is raised here."""
    from concurrent.futures import FIRST_COMPLETED, wait
    order = list(PARTS)
    after_driver = set(order[order.index("driver") + 1:])
    done: set[str] = set()
    running = {}
    waiting = list(order)
    while waiting or running:
        while len(running) < workers:
            held = after_driver if "driver" in waiting else set()
            name = next((n for n in waiting if n not in held and all(d in done for d in PARTS[n][0])), None)
            if name is None:
                break
            waiting.remove(name)
            running[pool.submit(warm_up, name)] = name
        if not running:
            raise RuntimeError(f"part {waiting[0]!r} waits for parts that never run")   # a need PARTS lacks
        finished, _ = wait(running, return_when=FIRST_COMPLETED)
        for fut in finished:
            fut.result()
            done.add(running.pop(fut))
