"""Batched pneumatic runs: many scenarios spread over threads.

Every scenario in a batch runs through exactly the same compiled serial code as
:func:`frogsim.simulate` (:func:`frogsim.engine.integrator.run_schedule`, compiled without the GIL),
on a pool of threads (:func:`frogsim._parallel.map_pieces`), so a point's result is bit-for-bit the
same whether it runs alone, in a batch of 10 or of 10,000, and whatever the chunking.

Points are variants of one base scenario (:meth:`frogsim.scenario.core.Scenario.replace`: dotted
path -> SI value) and their models are built by :func:`frogsim.circuit.model.build_model` itself,
so a point's model *is* the model of its scenario: exact by construction. Building stays cheap
because build_model assembles its arrays from parts cached on the settings each part reads
(see :mod:`frogsim.circuit.model`): a variant rebuilds only the parts its changes reach.
"""
from __future__ import annotations

from frogsim._parallel import default_threads, map_pieces
from frogsim.circuit.model import PneumaticModel, build_model
from frogsim.engine.integrator import STATUS_OK, run_schedule
from frogsim.engine.result import Result, valve_switchings
from frogsim.errors import ScenarioError, SimulationError
from frogsim.scenario.core import Scenario


def build_models(base: Scenario, points: list[dict]) -> list[PneumaticModel]:
    """The model of ``base.replace(point)`` for every point (dicts of dotted path -> SI value).

    Raises ScenarioError on the first invalid point, naming it, before anything runs.
    """
    models = []
    for k, pt in enumerate(points):
        try:
            models.append(build_model(base.replace(pt)))
        except ScenarioError as exc:
            shown = ", ".join(f"{p} = {v!r}" for p, v in pt.items()) or "the base scenario"
            raise ScenarioError(exc.field, exc.value, f"{exc.allowed} (in point {k}: {shown})") from None
    return models


def _run_one(m: PneumaticModel):
    sc = m.scenario
    return run_schedule(m.y0, 0.0, sc.duration, m.g, m.mp, m.mot_t, m.mot_L, m.mot_d, m.mot_n,
                        m.sched_t, m.sched_u, m.u0, 1.0 / sc.controller.rate, m.out_t, sc.solver.rtol,
                        m.atol, sc.solver.max_step, 1e-4, m.laws, 0)


def run_models(models: list[PneumaticModel], threads: int | None = None) -> list[Result]:
    """Run many models on ``threads`` threads (default: all cores); one Result per model, in order,
    each identical to ``simulate(model)``. Raises SimulationError naming the first failed point."""
    if not models:
        return []
    piece = max(1, len(models) // (8 * default_threads(threads)))
    raw = [r for part in map_pieces(lambda ms: [_run_one(m) for m in ms], models, piece, threads) for r in part]
    results = []
    for b, (m, (oy, ou, y_end, stats, status, t_r, cs, _, _)) in enumerate(zip(models, raw)):
        if status != STATUS_OK:
            raise SimulationError(f"batch point {b} ({m.scenario.name!r}): integration stopped at "
                                  f"t = {t_r:.6g} s (status {status})")
        results.append(Result(t=m.out_t, y=oy, u=ou, model=m,
                              stats={"steps": int(stats[0]), "rejected": int(stats[1]),
                                     "rhs_evaluations": int(stats[2]),
                                     "stiff_steps": int(stats[3])},
                              switchings=valve_switchings(m, cs)))
    return results
