"""The pneumatics-only engine: muscle lengths prescribed (the paper's Figure 8 model)."""
from __future__ import annotations

import numpy as np

from frogsim.circuit import layout as L
from frogsim.circuit.model import PneumaticModel, build_model
from frogsim.scenario.core import Scenario
from frogsim.engine.integrator import STATUS_OK, run_schedule
from frogsim.engine.result import Result
from frogsim.errors import SimulationError

_STATUS_TEXT = {1: "step size fell below 1e-14 s", 2: "the state became non-finite (NaN or inf)",
                3: "more than 50 million steps"}


def _as_model(what) -> PneumaticModel:
    if isinstance(what, PneumaticModel):
        return what
    if isinstance(what, Scenario):
        return build_model(what)
    from frogsim.scenario.load import load_scenario
    return build_model(load_scenario(what))


def _describe_state(model: PneumaticModel, y: np.ndarray) -> str:
    bad = []
    labels = ["source mass", "source pressure", "exhaust mass", "exhaust pressure"]
    for i, name in enumerate(model.names):
        labels += [f"{name} mass", f"{name} pressure"]
    for j, lab in enumerate(labels):
        if not np.isfinite(y[j]) or y[j] <= 0:
            bad.append(f"{lab} = {y[j]:.4g}")
    return "; ".join(bad) if bad else "all states finite and positive"


def simulate(scenario, h0: float = 1e-4) -> Result:
    """Run one scenario (a Scenario, a built model, a TOML path or a dict) and return its Result.

    Raises SimulationError naming the time and the offending quantity if integration fails.
    """
    model = _as_model(scenario)
    sc = model.scenario
    out_y, out_u, y_end, stats, status, t_reached = run_schedule(
        model.y0, 0.0, sc.duration, model.g, model.mp, model.mot_t, model.mot_L, model.mot_d,
        model.mot_n, model.sched_t, model.sched_u, model.u0, 1.0 / sc.controller.rate,
        model.out_t, sc.solver.rtol, model.atol, sc.solver.max_step, h0)
    if status != STATUS_OK:
        raise SimulationError(f"scenario {sc.name!r}: integration stopped at t = {t_reached:.6g} s: "
                              f"{_STATUS_TEXT.get(status, status)} ({_describe_state(model, y_end)})")
    # every output point interpolates accepted steps, whose error norm was finite: checking the
    # end state is enough to catch a run that went non-physical without going non-finite
    if not (np.all(np.isfinite(y_end)) and y_end[L.Y_PS] > 0 and y_end[L.Y_PE] > 0):
        raise SimulationError(f"scenario {sc.name!r}: non-physical end state "
                              f"({_describe_state(model, y_end)})")
    return Result(t=model.out_t, y=out_y, u=out_u, model=model,
                  stats={"steps": int(stats[0]), "rejected": int(stats[1]), "rhs_evaluations": int(stats[2])})
