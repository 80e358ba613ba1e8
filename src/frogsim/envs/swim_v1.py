"""``frogsim/Swim-v1``: swim forward for 20 s; the reward is the forward speed, its optimum a gait.

The plant is :class:`frogsim.engine.coupled.CoupledStepper` on a robot scenario (default the shipped
``swim``: six driving muscles with spring recovery, planar in water, pump on); each step holds the
commands for ``steps_per_action`` MuJoCo steps (default 10: 10 ms). Differences from ``Swim-v0``
(which stays as it was): an episode of 20 s (2,000 steps, Gymnasium's ``TimeLimit`` from the
registration) over which one stroke and a glide are worth less than a gait, a reward per step in
m/s with its terms named as in MuJoCo's v5 environments, a seeded start, the whole state observed,
bounds from physics, a normalisation option and rendering.

Action space
    ``MultiDiscrete([3] * n + [2])``: per muscle (order of ``env.unwrapped.muscle_names``)
    0 vent, 1 hold, 2 charge, acting after the valves' dead time (2 ms); then the palms: 0 fold,
    1 open (the steering motors move at their travel rate).
Observation space
    ``Box(float32, shape (5 n + 25,))`` (55 for the six-muscle robot), in this order
    (``env.unwrapped.obs_names`` names every entry with its unit):

    ============================  =====  =====================================================
    entries                       count  bounds (physics)
    ============================  =====  =====================================================
    leg joint angles [rad]        6      the joints' stop pads ± 0.1 rad (the pads hold a joint
                                         within millirad of its stop)
    leg joint velocities [rad/s]  6      ± 200 rad/s: the engine stops a run beyond
    hull forward, sideways        3      ± 20 m/s (the engine's limit), yaw rate ± 200 rad/s
    velocity [m/s], yaw rate
    heading: sin, cos of the yaw  2      [-1, 1]; relative to the heading at the reset
    muscle pressures [bar gauge]  n      [-p_atm, p_max]: vacuum to the source's highest
    source, exhaust [bar gauge]   2      pressure p_max (below)
    pump running (1) or not (0)   1      [0, 1]
    valves open now (1) or shut   2 n    [0, 1]: charge then discharge valve, per muscle
    valves as last commanded      2 n    [0, 1]: they differ from "now" while a command is still
                                         inside the dead time
    palms' opening                2      [0, 1] (0 folded, 1 open), left then right
    palms' target (last command)  1      [0, 1]
    gait phase: sin, cos          2      [-1, 1] of 2 pi t / ``phase_period`` (default 2 s,
                                         the paper's stroke period): a clock for the policy
    ============================  =====  =====================================================

    ``p_max`` is the highest pressure air can reach in the circuit: the source's start (times
    1 + ``reset_noise_scale``) or the pump's switch-off pressure, whichever is higher, plus 0.5 bar
    for the pump's band sampled at the controller's rate and a sealed muscle squeezed by the
    water. The observation is never clipped: a value outside these bounds would be a bug (the
    tests run episodes and check that none is). The hull's position is not observed (the task
    does not depend on it: the reward is a speed along the reset's heading, which is observed).
    Left out on purpose, as hidden state: the air temperatures in muscles and chambers (the
    shipped parameter sets are adiabatic: a muscle's temperature follows from its pressure and
    mass history), the water's memory of the last step's part velocities (added-mass
    accelerations) and, only when a dead time exceeds two action periods, the commands older
    than the last one that are still pending (with the default 2 ms against 10 ms, or even 1 ms
    per action, none is).

    ``normalize=True`` gives every entry as ``(x - offset) / scale`` (``env.unwrapped.obs_offset``,
    ``obs_scale``): joint angles mapped to [-1, 1] over their stops, joint velocities / 10 rad/s,
    hull velocities / 1 m/s, yaw rate / 1 rad/s, pressures / p_max (gauge); the rest is already
    in [-1, 1]. The bounds are mapped with them.
Reward (per step, in m/s)
    ``reward_forward = forward_reward_weight x`` forward progress in the step / the step's length
    (along the heading at the reset), plus ``reward_air = -air_cost_weight x`` air charged into
    the muscles in the step [standard litres, ISO 8778] / the step's length: the weight is metres
    a litre is worth (default 0.05 m/L). Both terms are in ``info`` with the speed
    (``x_velocity``), the air (``air_L_std``), the distance, the valve switchings and the time.
    With the defaults a step's reward is about 0.3-0.4 for a gait; a return over the 2,000 steps
    is 2,000 x the episode's mean reward (docs/control.md lists reference returns).
Start
    The shipped robot rests at its flexed stops, muscles at atmospheric pressure, source at 6 bar
    gauge. ``reset(seed=...)`` perturbs it by ``reset_noise_scale`` s (default 0.05): each leg joint
    angle uniformly within ± s rad of its start and inside its stops, each leg joint velocity
    uniformly in ± s rad/s, each muscle's pressure uniformly in [0, s] bar gauge (its air at the
    ambient temperature in its present volume) and the source's gauge pressure by a factor
    uniform in [1 - s, 1 + s] (its temperature kept). The same seed gives the same episode;
    ``reset_noise_scale=0`` the unperturbed start. The reset info gives the start
    (``start_joint_angles_rad``, ``start_source_bar_gauge``, ...).
Episode
    Not truncated by the environment itself: ``gymnasium.make`` wraps it in a ``TimeLimit`` of 2,000
    steps (20 s; change it with ``max_episode_steps=``). Terminated only when the simulation
    goes unstable (``info["failure"]`` says why). A step before the first reset or after a
    termination raises ``gymnasium.error.ResetNeeded``; after ``close()``,
    ``gymnasium.error.ClosedEnvironmentError``.
Rendering
    ``render_mode="rgb_array"``: :meth:`render` returns an (``height``, ``width``, 3) uint8 image of
    the MuJoCo model from camera ``camera`` (``"track"`` or ``"top"``), muscles red when
    pressurised and blue when vented, palms as open as they are. Drawn offscreen: MuJoCo reads
    its OpenGL backend from ``MUJOCO_GL`` when first imported, so set ``MUJOCO_GL=egl`` (or
    ``osmesa``) before importing frogsim on a machine without a display.
Pickling
    An environment pickles as its arguments: the copy is built anew, needs a ``reset`` and then
    gives the same episodes for the same seeds (vector environments pickle the functions that
    make the environments, not the environments).
Arguments (checked before anything is built; ValueError naming the argument, value and range)
    ``steps_per_action`` a whole number in [1, 100000]; ``forward_reward_weight``,
    ``air_cost_weight``, ``noise_std`` [bar] (Gaussian noise on the pressure readings, seeded by
    the reset) and ``reset_noise_scale`` finite and >= 0, the last <= 0.5; ``phase_period`` > 0 s;
    ``normalize`` a bool; ``render_mode`` None or "rgb_array"; ``width``, ``height`` whole
    numbers in [16, 4096]; ``camera`` "track" or "top". ``reset`` takes no options.
"""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from frogsim.circuit import layout as CL
from frogsim.control.signals import CS_PUMP
from frogsim.envs import checks
from frogsim.envs.plant import ACTIONS
from frogsim.errors import ScenarioError, SimulationError

BAR = 1e5
MAX_STEPS_PER_ACTION = 100_000       # MuJoCo steps held per action (100 s at 1 ms)
ANGLE_MARGIN = 0.1                   # [rad] beyond a joint's stop pad in the bounds
PRESSURE_MARGIN = 0.5                # [bar] above the highest source pressure in the bounds
MAX_NOISE = 0.5
CAMERAS = ("track", "top")
ACTION_MEANING = "per muscle 0 vent, 1 hold, 2 charge; then the palms 0 fold, 1 open"
#: typical magnitudes the normalised observation divides by
VELOCITY_SCALE = 10.0                # [rad/s]
HULL_SCALE = 1.0                     # [m/s], [rad/s]


class SwimEnv(gym.Env):
    """Swim forward at a low air cost over a long episode (module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 25}

    def __init__(self, scenario="swim", steps_per_action: int = 10, forward_reward_weight: float = 1.0,
                 air_cost_weight: float = 0.05, reset_noise_scale: float = 0.05, noise_std: float = 0.0,
                 phase_period: float = 2.0, normalize: bool = False, render_mode: str | None = None,
                 width: int = 480, height: int = 360, camera: str = "track"):
        from frogsim.engine.coupled import BODY_SPEED_LIMIT, JOINT_SPEED_LIMIT, CoupledStepper
        from frogsim.engine.coupled_layout import STOP_LOWER, STOP_UPPER
        from frogsim.engine.swim import as_robot_scenario
        self._init_kwargs = dict(scenario=scenario, steps_per_action=steps_per_action,
                                 forward_reward_weight=forward_reward_weight, air_cost_weight=air_cost_weight,
                                 reset_noise_scale=reset_noise_scale, noise_std=noise_std,
                                 phase_period=phase_period, normalize=normalize, render_mode=render_mode,
                                 width=width, height=height, camera=camera)
        steps_per_action = checks.whole("steps_per_action", steps_per_action, 1, MAX_STEPS_PER_ACTION)
        self.forward_reward_weight = checks.real("forward_reward_weight", forward_reward_weight, 0.0)
        self.air_cost_weight = checks.real("air_cost_weight", air_cost_weight, 0.0, unit="m/L")
        self.reset_noise_scale = checks.real("reset_noise_scale", reset_noise_scale, 0.0, MAX_NOISE)
        self.noise_std = checks.real("noise_std", noise_std, 0.0, unit="bar")
        self.phase_period = checks.real("phase_period", phase_period, 0.0, 1e6, low_open=True, unit="s")
        if not isinstance(normalize, (bool, np.bool_)):
            raise ScenarioError("normalize", normalize, "expected True or False")
        self.normalize = bool(normalize)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ScenarioError("render_mode", render_mode, "expected None or 'rgb_array'")
        self.render_mode = render_mode
        self.width = checks.whole("width", width, 16, 4096)
        self.height = checks.whole("height", height, 16, 4096)
        if camera not in CAMERAS:
            raise ScenarioError("camera", camera, f"expected one of {', '.join(CAMERAS)}")
        self.camera = camera
        rs = as_robot_scenario(scenario)
        self.stepper = CoupledStepper(rs, steps_per_action=steps_per_action)
        cm = self.stepper.cm
        self.muscle_names = list(cm.muscle_names)
        self.joint_names = list(cm.joint_names)
        n = len(self.muscle_names)
        self.n = n
        g = cm.pneumatic.g
        self.patm = float(g[CL.G_PATM])
        self.rho_ref = float(g[CL.G_RHOREF])
        self.action_space = spaces.MultiDiscrete([3] * n + [2])

        stops = cm.arrays["stops"]
        self.stop_low, self.stop_high = stops[:, STOP_LOWER].copy(), stops[:, STOP_UPPER].copy()
        pn = rs.pneumatic
        p_src = pn.source.initial_pressure_gauge * (1.0 + self.reset_noise_scale)
        if pn.pump.enabled:
            p_src = max(p_src, pn.pump.off_above_gauge)
        self.p_max = p_src / BAR + PRESSURE_MARGIN          # [bar gauge]
        p_min = -self.patm / BAR
        names, low, high, offset, scale = [], [], [], [], []

        def add(label, lo, hi, off=0.0, sc=1.0):
            names.append(label)
            low.append(lo)
            high.append(hi)
            offset.append(off)
            scale.append(sc)

        for j, name in enumerate(self.joint_names):
            lo, hi = self.stop_low[j], self.stop_high[j]
            add(f"angle {name} [rad]", lo - ANGLE_MARGIN, hi + ANGLE_MARGIN, 0.5 * (lo + hi), 0.5 * (hi - lo))
        for name in self.joint_names:
            add(f"angular velocity {name} [rad/s]", -JOINT_SPEED_LIMIT, JOINT_SPEED_LIMIT, 0.0, VELOCITY_SCALE)
        add("hull forward velocity [m/s]", -BODY_SPEED_LIMIT, BODY_SPEED_LIMIT, 0.0, HULL_SCALE)
        add("hull sideways velocity [m/s]", -BODY_SPEED_LIMIT, BODY_SPEED_LIMIT, 0.0, HULL_SCALE)
        add("hull yaw rate [rad/s]", -JOINT_SPEED_LIMIT, JOINT_SPEED_LIMIT, 0.0, HULL_SCALE)
        add("heading sin [-]", -1.0, 1.0)
        add("heading cos [-]", -1.0, 1.0)
        for name in self.muscle_names:
            add(f"pressure {name} [bar gauge]", p_min, self.p_max, 0.0, self.p_max)
        add("pressure source [bar gauge]", p_min, self.p_max, 0.0, self.p_max)
        add("pressure exhaust [bar gauge]", p_min, self.p_max, 0.0, self.p_max)
        add("pump running [0/1]", 0.0, 1.0)
        for when in ("now", "commanded"):
            for name in self.muscle_names:
                for valve in ("charge", "discharge"):
                    add(f"{valve} valve {name} open {when} [0/1]", 0.0, 1.0)
        add("palm left opening [0-1]", 0.0, 1.0)
        add("palm right opening [0-1]", 0.0, 1.0)
        add("palms target [0/1]", 0.0, 1.0)
        add("gait phase sin [-]", -1.0, 1.0)
        add("gait phase cos [-]", -1.0, 1.0)
        self.obs_names = names
        self.obs_offset = np.array(offset) if self.normalize else np.zeros(len(names))
        self.obs_scale = np.array(scale) if self.normalize else np.ones(len(names))
        low = (np.array(low) - self.obs_offset) / self.obs_scale
        high = (np.array(high) - self.obs_offset) / self.obs_scale
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self._obs_buf = np.empty(len(names))
        self._renderer = None
        self.steps = 0
        self.episode = checks.Episode()

    def __reduce__(self):
        """Pickled as its arguments: the copy is built anew and needs a reset (the coupled model's
        compiled views into MuJoCo's arrays cannot travel), then gives the same episodes."""
        return (_rebuild, (self._init_kwargs,))

    # -- observation -----------------------------------------------------------------------------
    def _obs(self) -> np.ndarray:
        s, o, n = self.stepper, self._obs_buf, self.n
        nj = len(self.joint_names)
        d, a = s.cm.mjd, s.cm.arrays
        o[:nj] = d.qpos[a["leg_qpos"]]
        o[nj:2 * nj] = d.qvel[a["leg_dof"]]
        k = 2 * nj
        o[k:k + 3] = s.body_velocity()
        yaw = s.heading() - self.h0
        o[k + 3], o[k + 4] = math.sin(yaw), math.cos(yaw)
        k += 5
        y = a["y"]
        o[k:k + n] = y[CL.pressure_slice(n)]
        o[k + n], o[k + n + 1] = y[CL.Y_PS], y[CL.Y_PE]
        p = o[k:k + n + 2]
        p -= self.patm
        p /= BAR
        if self.noise_std > 0:
            p += self.np_random.normal(0.0, self.noise_std, p.size)
        k += n + 2
        o[k] = a["cs"][CS_PUMP]
        k += 1
        o[k:k + 2 * n] = s.u_due
        o[k + 2 * n:k + 4 * n] = s.u_cmd
        k += 4 * n
        o[k:k + 2] = a["frac"]
        o[k + 2] = self.palm_target
        phase = 2.0 * math.pi * s.t / self.phase_period
        o[k + 3], o[k + 4] = math.sin(phase), math.cos(phase)
        if self.normalize:
            return ((o - self.obs_offset) / self.obs_scale).astype(np.float32)
        return o.astype(np.float32)

    def _forward(self) -> float:
        d = self.stepper.position()[:2] - self.x0
        return float(d[0] * math.cos(self.h0) + d[1] * math.sin(self.h0))

    # -- start -----------------------------------------------------------------------------------
    def _perturb(self) -> dict:
        """Perturb the start by reset_noise_scale (module docstring, "Start"); returns the start."""
        import mujoco
        from frogsim.engine.integrator import D_F_VALID
        s = self.stepper
        cm, a, rng, sc = s.cm, s.cm.arrays, self.np_random, self.reset_noise_scale
        m, d = cm.mjm, cm.mjd
        iq, iv = a["leg_qpos"], a["leg_dof"]
        q0 = d.qpos[iq].copy()
        lo = np.maximum(self.stop_low, q0 - sc)
        hi = np.minimum(self.stop_high, q0 + sc)
        d.qpos[iq] = rng.uniform(lo, hi)
        d.qvel[iv] = rng.uniform(-sc, sc, iv.size)
        mujoco.mj_step1(m, d)                 # tendon lengths (muscle volumes) at the new angles
        for name, p in zip(self.muscle_names, rng.uniform(0.0, sc, self.n)):
            cm.set_muscle_pressure(name, self.patm + p * BAR)
        y = a["y"]
        f = 1.0 + rng.uniform(-sc, sc)
        ps_new = self.patm + (y[CL.Y_PS] - self.patm) * f
        y[CL.Y_MS] *= ps_new / y[CL.Y_PS]     # same volume and temperature: mass in proportion
        y[CL.Y_PS] = ps_new
        a["ds"][D_F_VALID] = 0.0
        return {"start_joint_angles_rad": d.qpos[iq].copy(), "start_joint_velocities_rad_s": d.qvel[iv].copy(),
                "start_muscle_pressures_bar_gauge": (y[CL.pressure_slice(self.n)] - self.patm) / BAR,
                "start_source_bar_gauge": float((y[CL.Y_PS] - self.patm) / BAR)}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.episode.check_open("reset")
        super().reset(seed=seed)
        checks.options(options, ())
        self.stepper.reset()
        info = self._perturb()
        self.x0 = self.stepper.position()[:2]
        self.h0 = self.stepper.heading()
        self.palm_target = 0.0
        self.steps = 0
        self.distance = 0.0
        self.charged = 0.0
        self.episode.start()
        return self._obs(), info

    def close(self):
        """End the environment: a later step() or reset() raises
        ``gymnasium.error.ClosedEnvironmentError`` (calling close() again does nothing)."""
        self.episode.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()

    # -- step ------------------------------------------------------------------------------------
    def step(self, action):
        """One action period (module docstring); ResetNeeded after a termination."""
        self.episode.check_step()
        a = checks.action(self.action_space, action, ACTION_MEANING)
        u = np.array([v for x in a[:-1] for v in ACTIONS[int(x)]], float)
        self.palm_target = float(a[-1])
        try:
            switches = self.stepper.step(u, self.palm_target)
        except SimulationError as exc:
            self.episode.end(True, False, f"terminated: {exc}")
            return self._obs(), 0.0, True, False, {"failure": str(exc)}
        self.steps += 1
        period = self.stepper.period
        dist, charged = self._forward(), self.stepper.charged_mass()
        speed = (dist - self.distance) / period
        air_L = (charged - self.charged) / self.rho_ref * 1e3
        self.distance, self.charged = dist, charged
        r_fwd = self.forward_reward_weight * speed
        r_air = -self.air_cost_weight * air_L / period
        info = {"reward_forward": r_fwd, "reward_air": r_air, "x_velocity": speed, "air_L_std": air_L,
                "distance_m": dist, "switches": switches, "time_s": self.stepper.t}
        return self._obs(), float(r_fwd + r_air), False, False, info

    # -- rendering -------------------------------------------------------------------------------
    def render(self):
        """The present state as an (height, width, 3) uint8 image (render_mode "rgb_array");
        None without a render mode, as Gymnasium asks."""
        if self.render_mode is None:
            gym.logger.warn("render() without a render_mode: make the environment with "
                            "render_mode='rgb_array'")
            return None
        from frogsim.robot.geometry import palm_fan_angle
        from frogsim.robot.render import SceneRenderer
        s = self.stepper
        cm = s.cm
        if self._renderer is None:
            self._renderer = SceneRenderer(cm.xml, self.muscle_names, self.width, self.height, self.camera)
            robot = cm.rs.robot
            L = robot.legs.palm_length
            self._fan = (palm_fan_angle(robot.palms.folded_area, L), palm_fan_angle(robot.palms.open_area, L))
            self._p_full = max(float(cm.rs.pneumatic.source.initial_pressure_gauge), 1.0)
        phi_f, phi_o = self._fan
        fan = phi_f + cm.arrays["frac"] * (phi_o - phi_f)
        level = np.clip((s.pressures() - self.patm) / self._p_full, 0.0, 1.0)
        return self._renderer.draw(cm.mjd.qpos, fan, level)


def _rebuild(kwargs: dict) -> SwimEnv:
    return SwimEnv(**kwargs)
