"""Calibration of the values the paper leaves out, against the figures it does give.

The paper reports aeration volumes (standard litres charged per pressurise phase, Sec. 4.2) of
0.455 L for a hip muscle and 0.401 L for a knee or ankle muscle, computed with its model. The
contraction each muscle reached in that experiment is not given; with the braid angle derived
from the datasheet force and the chosen dead volume, it is the one free value that sets the
aeration volume. :func:`calibrate_stroke_contraction` finds it by root finding on the full model.
"""
from __future__ import annotations

from frogsim.engine.pneumatic import simulate
from frogsim.scenario.load import load_scenario
# the paper's figures live with its studies, which this module does not import back: so
# `python -m frogsim.studies.calibration` runs it once (no runpy warning of a module imported twice)
from frogsim.studies.paper import PAPER_AERATION_L


def aeration_for(base, muscle_type: str, contraction: float, muscle: str) -> float:
    """Aeration volume [L standard] of ``muscle`` with its type's stroke contraction set [-]."""
    sc = base.replace({f"muscle_types.{muscle_type}.stroke_contraction": contraction})
    return simulate(sc).aeration_volume(muscle) * 1e3


def calibrate_stroke_contraction(scenario="paper-cycle", muscle_type: str = "hip",
                                 muscle: str | None = None, target_L: float | None = None) -> float:
    """Stroke contraction [-] of a muscle type that gives the paper's aeration volume.

    Solves aeration(contraction) = target by Brent's method on [0, max_contraction].
    """
    from scipy.optimize import brentq  # here, not at import: it costs 0.4 s of every CLI start
    base = load_scenario(scenario)
    muscle = muscle or next(m for m, v in base.muscles.items() if v.type == muscle_type)
    target = PAPER_AERATION_L[muscle_type] if target_L is None else target_L
    hi = base.muscle_types[muscle_type].max_contraction
    return brentq(lambda e: aeration_for(base, muscle_type, e, muscle) - target, 0.0, hi, xtol=1e-6)


if __name__ == "__main__":
    for mtype in ("hip", "knee", "ankle"):
        eps = calibrate_stroke_contraction(muscle_type=mtype)
        print(f"{mtype}: stroke_contraction = {eps * 100:.2f} % -> target {PAPER_AERATION_L[mtype]} L")
