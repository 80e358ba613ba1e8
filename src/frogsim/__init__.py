"""frogsim: simulation and design tools for a frog-inspired swimming robot powered by pneumatic muscles.

Public API::

    import frogsim
    scenario = frogsim.load_scenario("paper-cycle")          # a TOML path, shipped name or dict
    result = frogsim.simulate(scenario)                       # -> Result
    hot = scenario.replace({"source.initial_pressure_gauge": 5e5})   # a variant: SI values
    df = result.to_dataframe()                                # SI columns, units in the names

    run = frogsim.swim("swim", cycles=10)                     # the robot in MuJoCo -> SwimResult
    run.summary()["mean_speed_m_per_s"]                       # m/s; see frogsim.engine.swim
"""
import frogsim.control  # noqa: F401  (registers the controller kinds before any scenario is loaded)
from frogsim.circuit.model import build_model
from frogsim.engine.pneumatic import simulate
from frogsim.engine.result import Result
from frogsim.engine.swim import SwimResult, swim
from frogsim.errors import FrogsimError, ScenarioError, SimulationError
from frogsim.scenario.core import Scenario
from frogsim.scenario.load import load_scenario, with_overrides
from frogsim.robot.scenario import load_robot_scenario

__all__ = ["FrogsimError", "Result", "Scenario", "ScenarioError", "SimulationError", "SwimResult", "build_model",
           "load_robot_scenario", "load_scenario", "simulate", "swim", "with_overrides"]
__version__ = "0.1.0"

# Gymnasium environments frogsim/HipPressure-v0 and frogsim/Swim-v0 (names only: cheap)
from frogsim.envs import register_envs as _register_envs  # noqa: E402

_register_envs()
