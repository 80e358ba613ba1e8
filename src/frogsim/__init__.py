"""frogsim: simulation and design tools for a frog-inspired swimming robot powered by pneumatic muscles.

Public API::

    import frogsim
    scenario = frogsim.load_scenario("paper-cycle")          # a TOML path, shipped name or dict
    result = frogsim.simulate(scenario)                       # -> Result
    df = result.to_dataframe()                                # SI columns, units in the names
"""
from frogsim.circuit.model import build_model
from frogsim.engine.pneumatic import simulate
from frogsim.engine.result import Result
from frogsim.errors import FrogsimError, ScenarioError, SimulationError
from frogsim.io.scenario import load_scenario, with_overrides

__all__ = ["FrogsimError", "Result", "ScenarioError", "SimulationError", "build_model",
           "load_scenario", "simulate", "with_overrides"]
__version__ = "0.1.0"
