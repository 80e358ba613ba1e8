"""Compiling the pneumatic engine in parts, so that two processes can share the first run's work."""
from __future__ import annotations

import numpy as np

from frogsim.circuit import layout as L
from frogsim.circuit.rhs import rhs
from frogsim.engine.integrator import STATS_SIZE, _accept, _dense, _dopri_step, _rosenbrock_step, begin
from frogsim.engine.measures import rise_times


def warm_up(part: str) -> None:
    """Compile (or load from the cache) one independent part of the pneumatic engine, on a
    one-muscle circuit with the argument types :func:`frogsim.engine.integrator.advance` passes:
    "rhs" (the circuit's right-hand side and the two methods' steps, which call it) or
    "controllers" (a run's start; an accepted step's work: the open-loop laws' samples inside it,
    the dense output, the stiffness test and the step-size control; the measures every study reads
    from its results). Two processes warming one part each, before anything calls the driver,
    compile them side by side; compiling the driver itself then finds all of them in the cache and
    has only its own loop left."""
    n = 1
    ny = L.state_size(n)
    vec = [np.zeros(ny) for _ in range(8)]
    stages = tuple(vec)                                 # (k2..k7, yt, yn), as advance cuts them
    stats = np.zeros(STATS_SIZE, np.int64)
    if part == "rhs":
        model = (np.ones(L.G_SIZE), np.zeros((n, L.M_SIZE)), np.zeros((n, 1)), np.ones((n, 1)), np.zeros((n, 1)),
                 np.ones(n, np.int64))
        y, f, atol, u, aux, work = np.ones(ny), np.zeros(ny), np.ones(ny), np.zeros(2 * n), np.zeros(2 * n + 1), \
            np.zeros(3 * n)
        rhs(0.0, y, u, 0.0, *model, f, aux, work)
        _dopri_step(0.0, 1e-3, 1e-3, y, f, u, 0.0, model, atol, 1e-7, stages, aux, work, stats)
        # Rosenbrock's work tuple (W, pivots, ft, k1, k2, k3, yt, f1, tder, J, T)
        wk = (np.zeros((ny, ny)),) + tuple(np.zeros(ny) for _ in range(8)) + (np.zeros((ny, ny)), np.zeros(ny))
        _rosenbrock_step(0.0, 1e-3, 1e-3, y, f, u, 0.0, model, atol, 1e-7, ny, wk, True, *vec[:6], aux, work,
                         stats)
    elif part == "controllers":
        # an open-loop run's laws: the 1-D pump row (frogsim.control.sampled.sampled_laws)
        _, _, y, u, ds, cs, _, commands = begin(np.ones(ny), 0.0, np.zeros(2 * n), np.zeros(0), np.zeros(0),
                                                np.zeros((0, 2 * n)), 1e-3, np.zeros(1), 1e-4)
        laws = commands[2]
        dense = tuple(np.zeros(ny) for _ in range(4))
        out = (np.zeros(1), np.zeros((1, ny)), np.zeros((1, 2 * n + 1)))
        _accept(ds, laws, cs, 0.0, 1e-3, 1e-3, 0.5, 1e-4, False, 0.0, 1.0, y, np.zeros(ny), stages, dense,
                np.zeros(ny), u, u.copy(), 0.0, out, 0, stats)
        _dense(y, *dense, 0.5, vec[0])
        t = np.linspace(0.0, 1.0, 11)
        rise_times(t, np.linspace(1e5, 2e5, 11)[None, :], np.full((1, 11), 2e5), np.ones((1, 11)), np.zeros(1))
    else:
        raise ValueError(f"unknown part {part!r}")
