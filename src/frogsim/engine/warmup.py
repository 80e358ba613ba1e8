"""Compiling the pneumatic engine in parts, so that two processes can share the first run's work."""
from __future__ import annotations

import numpy as np

from frogsim.circuit import layout as L
from frogsim.circuit.rhs import rhs
from frogsim.engine.integrator import _rosenbrock_step, begin
from frogsim.engine.measures import rise_times


def warm_up(part: str) -> None:
    """Compile (or load from the cache) one independent part of the pneumatic engine: "rhs" (the
    circuit's right-hand side) or "controllers" (the driver's start and the open-loop sampled laws). Two
    processes warming one part each, before anything calls the driver, compile them side by side;
    the driver itself then finds both in the cache."""
    if part == "rhs":
        n = 1
        ny = L.state_size(n)
        model = (np.ones(L.G_SIZE), np.zeros((n, L.M_SIZE)), np.zeros((n, 1)), np.ones((n, 1)), np.zeros((n, 1)),
                 np.ones(n, np.int64))
        rhs(0.0, np.ones(ny), np.zeros(2 * n), 0.0, *model, np.zeros(ny), np.zeros(2 * n + 1), np.zeros(3 * n))
        # the Rosenbrock step (the driver's largest part after the right-hand side), on the same types
        wk = (np.zeros((ny, ny)), np.zeros(ny), np.zeros(ny), np.zeros(ny), np.zeros(ny), np.zeros(ny), np.zeros(ny),
              np.zeros(ny), np.zeros(ny), np.zeros(ny * ny)[:].reshape((ny, ny)), np.zeros(ny)[:])
        _rosenbrock_step(0.0, 1e-3, 1e-3, np.ones(ny), np.zeros(ny), np.zeros(2 * n), 0.0, model, np.ones(ny),
                         1e-7, ny, wk, True, np.zeros(ny), np.zeros(ny), np.zeros(ny), np.zeros(ny), np.zeros(ny),
                         np.zeros(ny), np.zeros(2 * n + 1), np.zeros(3 * n), np.zeros(4, np.int64))
    elif part == "controllers":
        # an open-loop run's laws: the 1-D pump row (frogsim.control.sampled.sampled_laws)
        begin(np.ones(L.state_size(1)), 0.0, np.zeros(2), np.zeros(0), np.zeros(0), np.zeros((0, 2)),
              1e-3, np.zeros(1), 1e-4)
        # and the measures every study reads from its results (rise times, pressurise windows)
        t = np.linspace(0.0, 1.0, 11)
        rise_times(t, np.linspace(1e5, 2e5, 11)[None, :], np.full((1, 11), 2e5), np.ones((1, 11)), np.zeros(1))
    else:
        raise ValueError(f"unknown part {part!r}")
