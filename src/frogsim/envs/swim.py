"""``frogsim/Swim-v0``: the robot in water, its valves and palms commanded step by step.

The plant is :class:`frogsim.engine.coupled.CoupledStepper` on a robot scenario (default the
shipped ``swim``: six driving muscles with spring recovery, free in water, pump on); each step
holds the commands for ``steps_per_action`` MuJoCo steps (default 10: 10 ms).

Action space
    ``MultiDiscrete([3] * n + [2])``: per muscle (order of ``env.unwrapped.muscle_names``)
    0 vent, 1 hold, 2 charge, acting after the valves' dead time; then the palms: 0 fold, 1 open.
Observation space
    ``Box(float32, shape (6 + 6 + 3 + n + 1,))``: the six leg joint angles [rad] and angular
    velocities [rad/s] (hip, knee, ankle, left then right), the hull's forward and sideways velocity
    [m/s] and yaw rate [rad/s], the muscle pressures and the source pressure [bar gauge].
Reward
    forward progress in the step [m] (along the heading at the reset) ``- air_price x`` the air
    charged into the muscles in the step [standard litres, ISO 8778].
Episode
    ``duration`` [s] (default 4 s: two of the paper's 2 s strokes), then truncated; terminated
    when the simulation goes unstable (``info["failure"]``). Deterministic: no randomness unless
    ``noise_std`` [bar] adds sensor noise to the pressures (seeded by reset). A step before the
    first reset or after the episode ended raises ``gymnasium.error.ResetNeeded``; a step or a reset
    after ``close()`` raises ``gymnasium.error.ClosedEnvironmentError``.
Arguments (checked before anything is built; ValueError naming the argument, value and range)
    ``steps_per_action`` a whole number in [1, 100000]; ``duration`` (0, 1e6] s and at least one
    action period; ``air_price`` >= 0; ``noise_std`` >= 0 bar; ``reset`` takes no options. An
    action outside the action space (a muscle value other than 0, 1, 2, a palm value other than
    0, 1, the wrong length, a bool or a float) raises ValueError
    (:func:`frogsim.envs.checks.action`).
"""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from frogsim._words import count
from frogsim.circuit import layout as CL
from frogsim.envs import checks
from frogsim.envs.plant import valve_vector
from frogsim.errors import ScenarioError, SimulationError

BAR = 1e5
MAX_DURATION = 1e6                   # [s]
MAX_STEPS_PER_ACTION = 100_000       # MuJoCo steps held per action (100 s at 1 ms)
ACTION_MEANING = "per muscle 0 vent, 1 hold, 2 charge; then the palms 0 fold, 1 open"


class SwimEnv(gym.Env):
    """Swim forward at a low air cost (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, scenario="swim", steps_per_action: int = 10, duration: float = 4.0,
                 air_price: float = 0.05, noise_std: float = 0.0):
        from frogsim.engine.coupled import CoupledStepper
        from frogsim.engine.swim import as_robot_scenario
        steps_per_action = checks.whole("steps_per_action", steps_per_action, 1, MAX_STEPS_PER_ACTION)
        duration = checks.real("duration", duration, 0.0, MAX_DURATION, low_open=True, unit="s")
        air_price = checks.real("air_price", air_price, 0.0)
        noise_std = checks.real("noise_std", noise_std, 0.0, unit="bar")
        rs = as_robot_scenario(scenario)
        self.stepper = CoupledStepper(rs, steps_per_action=steps_per_action)
        if duration < self.stepper.period * (1 - 1e-9):
            raise ScenarioError("duration", duration, f"must be at least one action period "
                                                      f"({self.stepper.period:g} s)")
        cm = self.stepper.cm
        self.muscle_names = list(cm.muscle_names)
        self.joint_names = list(cm.joint_names)
        n = len(self.muscle_names)
        self.n = n
        self.patm = float(cm.pneumatic.g[CL.G_PATM])
        self.rho_ref = float(cm.pneumatic.g[CL.G_RHOREF])
        self.air_price = air_price
        self.noise_std = noise_std
        self.max_steps = max(1, int(math.floor(duration / self.stepper.period + 1e-9)))
        self.action_space = spaces.MultiDiscrete([3] * n + [2])
        nj = len(self.joint_names)
        # bounds: the engine stops a run past 200 rad/s at a joint or 20 m/s at the hull
        low = np.array([-2 * math.pi] * nj + [-250.0] * nj + [-25.0, -25.0, -250.0]
                       + [-1.5] * (n + 1), np.float32)
        high = np.array([2 * math.pi] * nj + [250.0] * nj + [25.0, 25.0, 250.0]
                        + [100.0] * (n + 1), np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.steps = 0
        self.episode = checks.Episode()

    def _obs(self) -> np.ndarray:
        s = self.stepper
        p = (np.concatenate([s.pressures(), [s.source_pressure()]]) - self.patm) / BAR
        if self.noise_std > 0:
            p = p + self.np_random.normal(0.0, self.noise_std, p.size)
        obs = np.concatenate([s.joint_angles(), s.joint_velocities(), s.body_velocity(), p])
        return np.clip(obs, self.observation_space.low, self.observation_space.high).astype(np.float32)

    def _forward(self) -> float:
        d = self.stepper.position()[:2] - self.x0
        return float(d[0] * math.cos(self.h0) + d[1] * math.sin(self.h0))

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.episode.check_open("reset")
        super().reset(seed=seed)
        checks.options(options, ())
        self.stepper.reset()
        self.x0 = self.stepper.position()[:2]
        self.h0 = self.stepper.heading()
        self.steps = 0
        self.distance = 0.0
        self.charged = 0.0
        self.episode.start()
        return self._obs(), {}

    def close(self):
        """End the environment: a later step() or reset() raises
        ``gymnasium.error.ClosedEnvironmentError`` (calling close() again does nothing)."""
        self.episode.close()
        super().close()

    def step(self, action):
        """One action period (module docstring); ResetNeeded once the episode has ended."""
        self.episode.check_step()
        a = checks.action(self.action_space, action, ACTION_MEANING)
        u = valve_vector(a[:-1])
        try:
            switches = self.stepper.step(u, float(a[-1]))
        except SimulationError as exc:
            self.episode.end(True, False, f"terminated: {exc}")
            return self._obs(), 0.0, True, False, {"failure": str(exc)}
        self.steps += 1
        dist, charged = self._forward(), self.stepper.charged_mass()
        progress = dist - self.distance
        air_L = (charged - self.charged) / self.rho_ref * 1e3
        self.distance, self.charged = dist, charged
        reward = progress - self.air_price * air_L
        info = {"progress_m": progress, "air_L_std": air_L, "distance_m": dist,
                "switches": switches, "time_s": self.stepper.t}
        truncated = self.steps >= self.max_steps
        self.episode.end(False, truncated, f"truncated after {count(self.steps, 'step')}, {self.stepper.t:g} s")
        return self._obs(), float(reward), False, truncated, info
