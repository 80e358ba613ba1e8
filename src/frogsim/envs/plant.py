"""The pneumatics-only plant stepped from outside: valve commands in, pressures out.

:class:`PneumaticPlant` takes a pneumatic scenario (one or more muscles; their lengths follow the
scenario's prescribed motions, the scenario's valve programs are not used) and advances it one
controller period per :meth:`PneumaticPlant.step`. The action is one command per muscle:

    0 vent    charge valve shut, discharge valve open
    1 hold    both shut
    2 charge  charge valve open, discharge valve shut

issued at the step's start (a controller sample) and acting after each valve's dead time
(``valves.charge.dead_time``, ``valves.discharge.dead_time``), exactly as a scenario's program
would; the pump's pressure band runs as in :func:`frogsim.simulate`. The integration is the one
stepping driver (:func:`frogsim.engine.integrator.advance`), called once per period: the state,
step size and controller memory carry over, so stepping a run changes none of its physics.

The observation is ``[p_1 .. p_n, p_source, p_exhaust, t]`` (pressures [Pa abs], time [s]); with
``noise_std`` > 0 [Pa] every pressure reading gets independent Gaussian noise from a generator
seeded by :meth:`PneumaticPlant.reset` (the plant's state itself is never noisy).
"""
from __future__ import annotations

import numpy as np

from frogsim.circuit import layout as L
from frogsim.circuit.model import PneumaticModel, build_model
from frogsim.control.sampled import sampled_laws
from frogsim.engine.integrator import D_SI, D_T, STATUS_OK, advance, begin, solver_group
from frogsim.errors import SimulationError

#: action value -> (charge valve, discharge valve), 1 open
ACTIONS = {0: (0.0, 1.0), 1: (0.0, 0.0), 2: (1.0, 0.0)}


def valve_vector(actions) -> np.ndarray:
    """The valve vector (:mod:`frogsim.circuit.layout`) of one action per muscle (keys of ACTIONS)."""
    u = np.empty(L.valve_size(len(actions)))
    for i, x in enumerate(actions):
        u[L.charge_valve(i)], u[L.vent_valve(i)] = ACTIONS[int(x)]
    return u
ACTION_NAMES = ("vent", "hold", "charge")
EPS = 1e-12


class PneumaticPlant:
    """A pneumatic scenario advanced one controller period per :meth:`step` (module docstring).

    ``control_period`` [s] defaults to the scenario's controller period (1 / controller.rate) and
    must be a whole multiple of it (commands are issued at the controller's samples).
    """

    def __init__(self, scenario, control_period: float | None = None, noise_std: float = 0.0,
                 h0: float = 1e-4):
        self.model = scenario if isinstance(scenario, PneumaticModel) else build_model(scenario)
        sc = self.model.scenario
        self.ctrl_dt = 1.0 / sc.controller.rate
        period = self.ctrl_dt if control_period is None else float(control_period)
        ratio = period / self.ctrl_dt
        if not (period > 0 and abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1):
            raise ValueError(f"control_period = {period:g} s: must be a whole multiple of the "
                             f"controller period {self.ctrl_dt:g} s")
        if noise_std < 0:
            raise ValueError(f"noise_std = {noise_std:g} Pa: must be >= 0")
        self.decimation = int(round(ratio))
        self.noise_std = float(noise_std)
        self.h0 = h0
        self.n = self.model.n
        m = self.model
        self.dead = L.per_valve(self.n, sc.valves.charge.dead_time, sc.valves.discharge.dead_time)
        self.circuit = (m.g, m.mp, m.mot_t, m.mot_L, m.mot_d, m.mot_n)
        self.solver = solver_group(sc.solver, m.atol)
        ny = m.y0.size
        self.no_output = (np.empty(0), np.empty((0, ny)), np.empty((0, 2 * self.n + 1)))
        # the prescribed motions' knots: kinks in dV/dt, where the integrator should stop
        knots = set()
        for i in range(self.n):
            if m.mp[i, L.M_FIXEDV] <= 0:
                knots.update(float(t) for t in m.mot_t[i, :int(m.mot_n[i])] if t > 0)
        self.knots = sorted(knots)
        self.reset()

    @property
    def period(self) -> float:
        """The control period [s]."""
        return self.decimation * self.ctrl_dt

    @property
    def t(self) -> float:
        return self.k * self.period

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Back to the scenario's initial state at t = 0 with every valve shut; returns the first
        observation. ``seed`` seeds the sensor noise."""
        m = self.model
        nu = L.valve_size(self.n)
        empty_t, empty_u = np.zeros(0), np.zeros((0, nu))
        # the pump's band only: the valves are the agent's (a scenario's closed-loop controllers
        # are not run here)
        laws = sampled_laws(m.g)
        _, _, y, u, ds, cs, stats, _ = begin(m.y0, 0.0, np.zeros(nu), m.mp, laws, empty_t, empty_u, self.ctrl_dt,
                                             np.zeros(0), self.h0)
        self.y, self.u, self.ds, self.cs, self.stats = y, u, ds, cs, stats
        self.laws = laws
        self.k = 0
        self.u_cmd = np.zeros(nu)
        self.u_due = np.zeros(nu)
        self.pending = [(t, -1, 0.0) for t in self.knots]   # valve -1: a stop, no change
        self.switches = 0
        self.rng = np.random.default_rng(seed)
        return self.observe()

    def valve_states(self, action) -> np.ndarray:
        """The valve vector (charge, discharge per muscle) of an action (module docstring)."""
        a = np.asarray(action).reshape(-1)
        if a.size != self.n or not all(int(x) == x and int(x) in ACTIONS for x in a):
            raise ValueError(f"action {a.tolist()}: expected {self.n} values in 0 (vent), 1 (hold), "
                             "2 (charge)")
        return valve_vector(a)

    def step(self, action) -> np.ndarray:
        """Issue the action at the present sample, advance one control period, return the
        observation. SimulationError if the integration fails (the plant then needs a reset)."""
        u = self.valve_states(action)
        t = self.t
        changed = np.nonzero(u != self.u_cmd)[0]
        for j in changed:
            self.pending.append((t + self.dead[j], int(j), float(u[j])))
        self.u_cmd = u
        self.switches += int(changed.size)
        self.last_switches = int(changed.size)
        t_end = (self.k + 1) * self.period
        sched_t, sched_u = self._due(t_end)
        self.ds[D_SI] = 0.0
        commands = (sched_t, sched_u, self.laws, self.ctrl_dt)
        status = advance(t_end, self.y, self.u, self.ds, self.cs, self.circuit, commands,
                         self.solver, self.no_output, self.stats)
        if status != STATUS_OK:
            raise SimulationError(f"scenario {self.model.scenario.name!r}: integration stopped at "
                                  f"t = {self.ds[D_T]:.6g} s (status {status})")
        self.k += 1
        return self.observe()

    def _due(self, t_end: float):
        """The schedule (times, full valve vectors) of the pending commands due by t_end."""
        self.pending.sort()
        due = [e for e in self.pending if e[0] <= t_end + EPS]
        self.pending = self.pending[len(due):]
        times, rows = [], []
        state = self.u_due.copy()
        for te, j, val in due:
            if j >= 0:
                state[j] = val
            if times and abs(times[-1] - te) < EPS:
                rows[-1] = state.copy()
            else:
                times.append(te)
                rows.append(state.copy())
        self.u_due = state
        return np.array(times, float), np.array(rows, float).reshape(len(times), 2 * self.n)

    # -- readings --------------------------------------------------------------------------------
    def pressures(self) -> np.ndarray:
        """True muscle pressures [Pa abs]."""
        return self.y[L.pressure_slice(self.n)].copy()

    def observe(self) -> np.ndarray:
        """``[p_1 .. p_n, p_source, p_exhaust, t]`` with the sensor noise on the pressures."""
        p = np.concatenate([self.pressures(), [self.y[L.Y_PS], self.y[L.Y_PE]]])
        if self.noise_std > 0:
            p = p + self.rng.normal(0.0, self.noise_std, p.size)
        return np.concatenate([p, [self.t]])

    def total_air_mass(self) -> float:
        """Air in source, exhaust and muscles [kg] (constant in the closed circuit)."""
        y = self.y
        return float(y[L.Y_MS] + y[L.Y_ME] + y[L.mass_slice(self.n)].sum())

    def charged_mass(self) -> float:
        """Air charged into all muscles since the reset [kg]."""
        return float(self.y[L.charged_slice(self.n)].sum())
