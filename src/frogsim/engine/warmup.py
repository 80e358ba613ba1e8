"""Compiling the pneumatic engine in parts, so that two processes can share the first run's work."""
from __future__ import annotations

import numpy as np

from frogsim.circuit import layout as L
from frogsim.circuit.rhs import rhs
from frogsim.engine.integrator import begin


def warm_up(part: str) -> None:
    """Compile (or load from the cache) one independent part of the pneumatic engine: "rhs" (the
    circuit's right-hand side) or "controllers" (the driver's start and the open-loop sampled laws). Two
    processes warming one part each, before anything calls the driver, compile them side by side;
    the driver itself then finds both in the cache."""
    if part == "rhs":
        n = 1
        ny = L.state_size(n)
        rhs(0.0, np.ones(ny), np.zeros(2 * n), 0.0, np.ones(L.G_SIZE), np.zeros((n, L.M_SIZE)), np.zeros((n, 1)),
            np.ones((n, 1)), np.zeros((n, 1)), np.ones(n, np.int64), np.zeros(ny), np.zeros(2 * n + 1),
            np.zeros(3 * n))
    elif part == "controllers":
        # an open-loop run's laws: the 1-D pump row (frogsim.control.sampled.sampled_laws)
        begin(np.ones(L.state_size(1)), 0.0, np.zeros(2), np.zeros(0), np.zeros(0), np.zeros((0, 2)),
              1e-3, np.zeros(1), 1e-4)
    else:
        raise ValueError(f"unknown part {part!r}")
