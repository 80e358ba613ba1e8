"""``frogsim/HipPressure-v1``: ``HipPressure-v0`` with the valves observed and a seeded start.

The plant, action, reward and arguments are those of ``HipPressure-v0``
(:mod:`frogsim.envs.hip`, which stays as it was) less ``duration``; what changes:

Observation space
    ``Box(float32, shape (5 n + 3,))``: ``[p_1 .. p_n, p_source, p_exhaust]`` [bar gauge] (with
    the optional sensor noise ``noise_std`` [bar]), the setpoint [bar gauge], then per muscle
    its charge and discharge valve open (1) or shut (0) now, then the same as last commanded.
    The two differ while a command is still inside the valves' dead time (2 ms against 1 ms
    steps: the last action's changes act one step later), so the observation is the whole state
    as long as a dead time is at most two control periods; older pending commands (a longer
    dead time) are not observed. The time is no longer observed: the task does not depend on
    it. Bounds from physics: pressures from vacuum (-p_atm) to the source's highest pressure
    p_max (its start times 1 + ``reset_noise_scale``, or the pump's switch-off pressure if higher,
    plus 0.5 bar), the setpoint within [0, 100] bar gauge (what it may be set to); never
    clipped.
    ``normalize=True`` divides the pressures and the setpoint by p_max (``env.unwrapped.obs_scale``).
Start
    ``reset(seed=...)`` draws the setpoint as v0 does and perturbs the start by
    ``reset_noise_scale`` s in [0, 0.5] (default 0.05): each muscle's pressure uniformly in [0, s]
    bar gauge and the source's gauge pressure by a factor uniform in [1 - s, 1 + s] (air masses
    in proportion: volumes and temperatures kept). The reset info gives the setpoint and the start.
Episode
    Not truncated by the environment: ``gymnasium.make`` wraps it in a ``TimeLimit`` of 500 steps
    (0.5 s; ``max_episode_steps=`` changes it). Terminated only when the integration fails.
Info
    ``reward_error`` (-|p_1 - setpoint| [bar]) and ``reward_switch`` (-``switch_price`` x valve
    changes) sum to the reward; ``error_bar``, ``switches``, ``time_s`` as in v0.
"""
from __future__ import annotations

import numpy as np
from gymnasium import spaces

from frogsim.circuit import layout as CL
from frogsim.envs import checks
from frogsim.envs import hip as v0
from frogsim.errors import ScenarioError, SimulationError

BAR = v0.BAR
PRESSURE_MARGIN = 0.5                # [bar] above the highest source pressure in the bounds
MAX_NOISE = 0.5


class HipPressureEnv(v0.HipPressureEnv):
    """Track a pressure setpoint in a muscle, the valves observed (module docstring)."""

    def __init__(self, scenario=None, control_period: float | None = None, switch_price: float = 0.01,
                 noise_std: float = 0.0, setpoint: float | None = None, setpoint_range: tuple = (1.0, 5.0),
                 reset_noise_scale: float = 0.05, normalize: bool = False):
        self.reset_noise_scale = checks.real("reset_noise_scale", reset_noise_scale, 0.0, MAX_NOISE)
        if not isinstance(normalize, (bool, np.bool_)):
            raise ScenarioError("normalize", normalize, "expected True or False")
        self.normalize = bool(normalize)
        super().__init__(scenario=scenario, control_period=control_period, switch_price=switch_price,
                         noise_std=noise_std, setpoint=setpoint, setpoint_range=setpoint_range)
        n = self.plant.n
        sc = self.plant.model.scenario
        p_src = sc.source.initial_pressure_gauge * (1.0 + self.reset_noise_scale)
        if sc.pump.enabled:
            p_src = max(p_src, sc.pump.off_above_gauge)
        self.p_max = p_src / BAR + PRESSURE_MARGIN
        lo_sp, hi_sp = v0.SETPOINT_LOW, v0.P_HIGH        # what a reset option may set
        low = np.array([-self.patm / BAR] * (n + 2) + [lo_sp] + [0.0] * (4 * n))
        high = np.array([self.p_max] * (n + 2) + [hi_sp] + [1.0] * (4 * n))
        self.obs_scale = np.array([self.p_max if self.normalize else 1.0] * (n + 3) + [1.0] * (4 * n))
        self.observation_space = spaces.Box((low / self.obs_scale).astype(np.float32),
                                            (high / self.obs_scale).astype(np.float32), dtype=np.float32)

    def _obs(self, raw: np.ndarray) -> np.ndarray:
        p = (raw[:-1] - self.patm) / BAR
        o = np.concatenate([p, [self.setpoint], self.plant.u_due, self.plant.u_cmd])
        return (o / self.obs_scale).astype(np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        from frogsim.engine.integrator import D_F_VALID
        _, info = super().reset(seed=seed, options=options)
        plant, rng, s = self.plant, self.np_random, self.reset_noise_scale
        y, n = plant.y, plant.n
        for i, p in enumerate(rng.uniform(0.0, s, n)):
            p_new = self.patm + p * BAR
            y[CL.mass_index(i)] *= p_new / y[CL.pressure_index(i)]
            y[CL.pressure_index(i)] = p_new
        ps_new = self.patm + (y[CL.Y_PS] - self.patm) * (1.0 + rng.uniform(-s, s))
        y[CL.Y_MS] *= ps_new / y[CL.Y_PS]
        y[CL.Y_PS] = ps_new
        plant.ds[D_F_VALID] = 0.0
        info.update(start_muscle_pressures_bar_gauge=(plant.pressures() - self.patm) / BAR,
                    start_source_bar_gauge=float((y[CL.Y_PS] - self.patm) / BAR))
        return self._obs(plant.observe()), info

    def step(self, action):
        """One control period; never truncated here (the registration's TimeLimit is)."""
        self.episode.check_step()
        action = checks.action(self.action_space, action, v0.ACTION_MEANING)
        try:
            raw = self.plant.step(action)
        except SimulationError as exc:
            self.episode.end(True, False, f"terminated: {exc}")
            raw = np.concatenate([self.plant.pressures(), self.plant.y[[CL.Y_PS, CL.Y_PE]], [self.plant.t]])
            return self._obs(raw), 0.0, True, False, {"failure": str(exc)}
        self.steps += 1
        error = (self.plant.pressures()[0] - self.patm) / BAR - self.setpoint
        r_err = -abs(error)
        r_sw = -self.switch_price * self.plant.last_switches
        info = {"reward_error": r_err, "reward_switch": r_sw, "error_bar": float(error),
                "switches": self.plant.last_switches, "time_s": self.plant.t}
        return self._obs(raw), float(r_err + r_sw), False, False, info
