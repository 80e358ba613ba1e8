"""``frogsim/HipPressure-v0``: bring a hip muscle to a pressure setpoint with on/off valves.

The plant is :class:`frogsim.envs.plant.PneumaticPlant` on a one-muscle scenario (by default a hip
DMSP-20 muscle held at its rest length, fed from the fan2017 parameter set's 4 L source at 6 bar
gauge, valves with their 2 ms dead time, controller at 1 kHz).

Action space
    ``MultiDiscrete([3] * n)``: per muscle 0 vent, 1 hold, 2 charge, issued every control period
    (default the controller period, 1 ms) and acting after the valves' dead time.
Observation space
    ``Box(float32, shape (n + 4,))``: ``[p_1 .. p_n, p_source, p_exhaust]`` [bar gauge], with the
    optional sensor noise ``noise_std`` [bar]; then the time [s] and the setpoint [bar gauge].
Reward
    ``-|p_1 - setpoint|`` [bar] (the true pressure after the step) ``- switch_price x`` the number
    of valve state changes the action commanded (a charge -> vent command changes two valves).
Episode
    ``duration`` [s] of simulated time (default 0.5 s), then truncated; terminated only when the
    integration fails (``info["failure"]`` says why). The setpoint is drawn uniformly from
    ``setpoint_range`` [bar gauge] by :meth:`reset` (seeded), unless ``setpoint`` fixes it or
    ``reset(options={"setpoint": x})`` gives it for one episode. A step before the first reset or
    after the episode ended raises ``gymnasium.error.ResetNeeded``; a step or a reset after
    ``close()`` raises ``gymnasium.error.ClosedEnvironmentError``.
Arguments (checked before anything is built; ValueError naming the argument, value and range)
    ``duration`` (0, 1e6] s and at least one control period; ``control_period`` > 0 s, a whole
    multiple of the controller period; ``switch_price`` >= 0; ``noise_std`` >= 0 bar;
    ``setpoint`` and both ends of ``setpoint_range`` (low <= high) in [0, 100] bar gauge. An
    action outside the action space (a value other than 0, 1, 2, the wrong length, a bool or a
    float) raises ValueError (:func:`frogsim.envs.checks.action`).
"""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from frogsim._words import count
from frogsim.circuit import layout as CL
from frogsim.envs import checks
from frogsim.envs.plant import PneumaticPlant
from frogsim.errors import ScenarioError, SimulationError

BAR = 1e5
P_LOW, P_HIGH = -1.5, 100.0          # [bar gauge]: bounds of any pressure reading
SETPOINT_LOW = 0.0                   # [bar gauge]: the muscle vents to the exhaust, at the atmosphere
MAX_DURATION = 1e6                   # [s]: the observation space's bound on the time
ACTION_MEANING = "per muscle 0 vent, 1 hold, 2 charge"


def hip_scenario(source_pressure_gauge: str = "6 bar", duration: float = 0.5):
    """The default plant: one hip muscle at its rest length (constant motion)."""
    from frogsim.scenario.load import load_scenario
    return load_scenario({
        "name": "hip-pressure", "parameters": "fan2017", "duration": f"{duration:g} s",
        "output_interval": f"{min(0.01, duration):g} s", "controller": {"rate": "1 kHz"},
        "source": {"initial_pressure_gauge": source_pressure_gauge},
        "muscles": {"hip": {"type": "hip", "program": {"pressurise": f"{duration:g} s",
                                                        "release": f"{duration:g} s"},
                            "motion": {"kind": "constant"}}}})


class HipPressureEnv(gym.Env):
    """Track a pressure setpoint in a muscle (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, scenario=None, duration: float = 0.5, control_period: float | None = None,
                 switch_price: float = 0.01, noise_std: float = 0.0, setpoint: float | None = None,
                 setpoint_range: tuple = (1.0, 5.0)):
        duration = checks.real("duration", duration, 0.0, MAX_DURATION, low_open=True, unit="s")
        if control_period is not None:
            control_period = checks.real("control_period", control_period, 0.0, low_open=True, unit="s")
        switch_price = checks.real("switch_price", switch_price, 0.0)
        noise_std = checks.real("noise_std", noise_std, 0.0, unit="bar")
        if setpoint is not None:
            setpoint = _setpoint("setpoint", setpoint)
        if not isinstance(setpoint_range, (tuple, list)) or len(setpoint_range) != 2:
            raise ScenarioError("setpoint_range", setpoint_range, "expected (low, high) [bar gauge]")
        lo, hi = (_setpoint(f"setpoint_range[{j}]", x) for j, x in enumerate(setpoint_range))
        if lo > hi:
            raise ScenarioError("setpoint_range", setpoint_range, "low must be <= high")
        self.plant = PneumaticPlant(scenario if scenario is not None else hip_scenario(duration=duration),
                                    control_period=control_period, noise_std=noise_std * BAR)
        n = self.plant.n
        if duration < self.plant.period * (1 - 1e-9):
            raise ScenarioError("duration", duration, f"must be at least one control period "
                                                             f"({self.plant.period:g} s)")
        self.patm = float(self.plant.model.g[CL.G_PATM])
        self.max_steps = max(1, int(math.floor(duration / self.plant.period + 1e-9)))
        self.switch_price = switch_price
        self.fixed_setpoint = setpoint
        self.setpoint_range = (lo, hi)
        self.action_space = spaces.MultiDiscrete([3] * n)
        low = np.array([P_LOW] * (n + 2) + [0.0, P_LOW], np.float32)
        high = np.array([P_HIGH] * (n + 2) + [np.float32(1e6), P_HIGH], np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.setpoint = float(setpoint) if setpoint is not None else float(np.mean(self.setpoint_range))
        self.steps = 0
        self.episode = checks.Episode()

    def _obs(self, raw: np.ndarray) -> np.ndarray:
        p = (raw[:-1] - self.patm) / BAR
        return np.concatenate([p, [raw[-1], self.setpoint]]).astype(np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.episode.check_open("reset")
        super().reset(seed=seed)
        options = checks.options(options, ("setpoint",))
        if "setpoint" in options:
            self.setpoint = _setpoint("options['setpoint']", options["setpoint"])
        elif self.fixed_setpoint is not None:
            self.setpoint = float(self.fixed_setpoint)
        else:
            self.setpoint = float(self.np_random.uniform(*self.setpoint_range))
        noise_seed = int(self.np_random.integers(2**63 - 1))
        raw = self.plant.reset(seed=noise_seed)
        self.steps = 0
        self.episode.start()
        return self._obs(raw), {"setpoint_bar_gauge": self.setpoint}

    def close(self):
        """End the environment: a later step() or reset() raises
        ``gymnasium.error.ClosedEnvironmentError`` (calling close() again does nothing)."""
        self.episode.close()
        super().close()

    def step(self, action):
        """One control period (module docstring); ResetNeeded once the episode has ended."""
        self.episode.check_step()
        action = checks.action(self.action_space, action, ACTION_MEANING)
        try:
            raw = self.plant.step(action)
        except SimulationError as exc:
            obs = self._obs(np.concatenate([self.plant.pressures(), self.plant.y[[CL.Y_PS, CL.Y_PE]],
                                            [self.plant.t]]))
            self.episode.end(True, False, f"terminated: {exc}")
            return np.clip(obs, self.observation_space.low, self.observation_space.high), 0.0, True, \
                False, {"failure": str(exc)}
        self.steps += 1
        p = (self.plant.pressures()[0] - self.patm) / BAR
        error = p - self.setpoint
        reward = -abs(error) - self.switch_price * self.plant.last_switches
        info = {"error_bar": float(error), "switches": self.plant.last_switches,
                "time_s": self.plant.t}
        truncated = self.steps >= self.max_steps
        self.episode.end(False, truncated, f"truncated after {count(self.steps, 'step')}, {self.plant.t:g} s")
        return self._obs(raw), float(reward), False, truncated, info


def _setpoint(name: str, value) -> float:
    return checks.real(name, value, SETPOINT_LOW, P_HIGH, unit="bar gauge")
