"""Step interfaces and Gymnasium environments: closed-loop valve control of the plant and the robot.

* :class:`frogsim.envs.plant.PneumaticPlant`: the pneumatics-only plant, ``reset(seed)`` /
  ``step(action)`` with per-muscle vent/hold/charge commands;
* :class:`frogsim.engine.coupled.CoupledStepper`: the robot in water, one controller period per
  ``step(u, palm)``;
* Gymnasium environments, registered when frogsim is imported (if Gymnasium is installed):
  ``frogsim/HipPressure-v0`` (:mod:`frogsim.envs.hip`), ``frogsim/Swim-v0``
  (:mod:`frogsim.envs.swim`), and their successors ``frogsim/HipPressure-v1``
  (:mod:`frogsim.envs.hip_v1`: the valves observed, a seeded start) and ``frogsim/Swim-v1``
  (:mod:`frogsim.envs.swim_v1`: a 20 s task whose optimum is swimming, the whole state observed,
  rendering). Registration names the entry points only: nothing heavy is imported until
  ``gymnasium.make``. The v0 environments truncate their own episodes (``duration``); the v1
  ones are truncated by the ``TimeLimit`` their registration's ``max_episode_steps`` sets, as
  Gymnasium's own environments are.
"""
from __future__ import annotations

#: env id -> entry point
ENVS = {
    "frogsim/HipPressure-v0": "frogsim.envs.hip:HipPressureEnv",
    "frogsim/Swim-v0": "frogsim.envs.swim:SwimEnv",
    "frogsim/HipPressure-v1": "frogsim.envs.hip_v1:HipPressureEnv",
    "frogsim/Swim-v1": "frogsim.envs.swim_v1:SwimEnv",
}
#: env id -> the registration's other arguments (the v0 environments truncate their own episodes).
#: Swim-v1's reward_threshold is the return of the paper's 1 s / 1 s gait over the 2,000 steps
#: (docs/control.md, "Reference returns"; benchmarks/bench_rl.py recomputes it): a policy that
#: reaches it swims as well as the paper's robot.
SPECS = {
    "frogsim/HipPressure-v1": {"max_episode_steps": 500},
    "frogsim/Swim-v1": {"max_episode_steps": 2000, "reward_threshold": 700.0},
}


def register_envs() -> list:
    """Register the environments with Gymnasium (once); returns the ids, [] without Gymnasium."""
    import importlib.util
    if importlib.util.find_spec("gymnasium") is None:
        return []
    from gymnasium.envs.registration import register, registry
    for env_id, entry in ENVS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry, **SPECS.get(env_id, {}))
    return list(ENVS)
