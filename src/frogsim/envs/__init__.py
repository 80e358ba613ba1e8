"""Step interfaces and Gymnasium environments: closed-loop valve control of the plant and the robot.

* :class:`frogsim.envs.plant.PneumaticPlant`: the pneumatics-only plant, ``reset(seed)`` /
  ``step(action)`` with per-muscle vent/hold/charge commands;
* :class:`frogsim.engine.coupled.CoupledStepper`: the robot in water, one controller period per
  ``step(u, palm)``;
* Gymnasium environments, registered when frogsim is imported (if Gymnasium is installed):
  ``frogsim/HipPressure-v0`` (:mod:`frogsim.envs.hip`) and ``frogsim/Swim-v0``
  (:mod:`frogsim.envs.swim`). Registration names the entry points only: nothing heavy is imported
  until ``gymnasium.make``.
"""
from __future__ import annotations

#: env id -> entry point (the environments truncate their own episodes)
ENVS = {
    "frogsim/HipPressure-v0": "frogsim.envs.hip:HipPressureEnv",
    "frogsim/Swim-v0": "frogsim.envs.swim:SwimEnv",
}


def register_envs() -> list:
    """Register the environments with Gymnasium (once); returns the ids, [] without Gymnasium."""
    import importlib.util
    if importlib.util.find_spec("gymnasium") is None:
        return []
    from gymnasium.envs.registration import register, registry
    for env_id, entry in ENVS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry)
    return list(ENVS)
