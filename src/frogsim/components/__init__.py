"""Typed, frozen parameter dataclasses and the generic validating builder that fills them."""
from frogsim.components.schema import (  # noqa: F401
    Air, Chamber, Controller, Motion, Muscle, MuscleType, Program, Pump, Scenario, Solver, Supply,
    Valve, Valves,
)
