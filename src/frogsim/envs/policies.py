"""Reference policies for ``frogsim/Swim-v1`` and a helper that runs an episode.

* :func:`gait_actions`: a robot scenario's open-loop gait (its muscle programs and palm commands,
  as :func:`frogsim.swim` runs them) as the environment's actions, one row per step: each
  muscle's valve state at the step's start (charge, vent or hold) and the palms' target. The
  gait's commands fall on the controller's 1 ms grid; the environment samples them at its own
  action period (10 ms by default), so a command between two steps acts at the next one.
* :func:`constant_action`: every muscle charging or holding, palms open or folded.
* :func:`run_episode`: the return of one episode of a policy.
"""
from __future__ import annotations

import numpy as np

from frogsim.scenario.motion import command_time
from frogsim.scenario.schema import VALVE_STATES

#: valve state name -> the environments' action value
ACTION_OF = {"vent": 0, "hold": 1, "charge": 2}
CONSTANT_POLICIES = {f"all-{m}, palms {p}": (m, p) for m in ("charge", "hold") for p in ("open", "folded")}


def gait_actions(rs, muscle_names, period: float, n_steps: int) -> np.ndarray:
    """(n_steps, n + 1) int64 actions of the robot scenario ``rs``'s gait, sampled every
    ``period`` [s] (its cycles repeated as far as needed)."""
    from frogsim.control.gait import palm_commands
    assert set(VALVE_STATES) == set(ACTION_OF)
    rate = rs.pneumatic.controller.rate
    gait = rs.gait
    cycle_steps = int(round(gait.period / period))
    if abs(cycle_steps * period - gait.period) > 1e-9:
        raise ValueError(f"the gait's period {gait.period:g} s is not a whole number of steps of {period:g} s")
    t = np.arange(cycle_steps) * period
    out = np.ones((cycle_steps, len(muscle_names) + 1), np.int64)
    for i, name in enumerate(muscle_names):
        steps = rs.pneumatic.muscles[name].program.steps
        for ts, state in steps:
            out[t >= command_time(ts, rate) - 1e-12, i] = ACTION_OF[state]
    pal_t, pal_v = palm_commands(gait, rate)
    out[:, -1] = 0
    for ts, v in zip(pal_t, pal_v):
        out[t >= ts - 1e-12, -1] = int(v)
    reps = -(-n_steps // cycle_steps)
    return np.tile(out, (reps, 1))[:n_steps]


def constant_action(n: int, muscles: str, palms: str) -> np.ndarray:
    """Every muscle ``muscles`` ("charge" or "hold"), the palms ``palms`` ("open" or "folded")."""
    return np.array([ACTION_OF[muscles]] * n + [1 if palms == "open" else 0], np.int64)


def run_episode(env, policy, seed: int | None = None) -> dict:
    """Run one episode of ``env`` (a ``gymnasium.make`` environment with its TimeLimit) with
    ``policy(obs, k) -> action`` from the reset with ``seed``; returns the return, the steps, the
    summed reward terms and the distance."""
    obs, _ = env.reset(seed=seed)
    total, k, terms, done, info = 0.0, 0, {}, False, {}
    while not done:
        obs, r, term, trunc, info = env.step(policy(obs, k))
        total += r
        for key, v in info.items():
            if key.startswith("reward_"):
                terms[key] = terms.get(key, 0.0) + v
        k += 1
        done = term or trunc
    return {"return": total, "steps": k, "terms": terms, "distance_m": info.get("distance_m", float("nan")),
            "terminated": bool(term)}
