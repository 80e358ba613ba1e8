"""Run a robot scenario and read off how fast, how far per stroke and at what air cost.

    import frogsim
    result = frogsim.swim("swim", cycles=10)          # a scenario name, TOML path, dict or RobotScenario
    result.summary()                                  # the figures of summary.json
    df = result.to_dataframe(units="display")         # joint angles, pressures, position, velocity

Definitions used by :meth:`SwimResult.summary` (all from the run's own records):

* forward: along the heading the hull had at t = 0 (the way the frog faces);
* thrust: the water's force on both legs (thighs, cruses, palms: drag and added-mass reaction)
  along the hull's current heading, over the MuJoCo step that ends at the sample; the hull's own
  drag is reported apart. Its peak over the run may fall where a leg meets a joint's stop pad (the
  water's added mass runs on); the peak during extension is given apart (on the output grid);
* extension / recovery: the hip driving muscles' pressurise phase of each cycle / the rest of it;
* air used: mass charged into the muscles through their charge valves, as litres at the ISO 8778
  standard state (100 kPa, 293.15 K);
* cost of transport: E / (m g d), with E the isothermal exergy of the charged air
  (m_air R T_ambient ln(p_source / p_atm), the least work that could have compressed it), m the
  robot's mass with ballast, d the forward distance; null when d <= 0, as is the air per metre,
  with ``cost_of_transport_reason`` saying why;
* aeration volume: the air a muscle took in during its first pressurise phase (as
  :meth:`frogsim.engine.run_result.RunResult.aeration_volume`); null for a muscle whose valves
  no program opens (one under closed-loop control);
* joint delay: from the first charge command to the joint having moved 5 % of its excursion in
  that pressurise phase.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from frogsim.circuit import layout as CL
from frogsim.engine import coupled as C
from frogsim.engine.run_result import RunResult, valve_switchings

DELAY_FRACTION = 0.05


@dataclass
class SwimResult(RunResult):
    """Records of one robot run on the output grid (SI inside), with the model that made them.

    What it shares with a pneumatic run's result (the circuit's constants, aeration volume,
    setpoints, the controllers' metrics) is written once in
    :class:`frogsim.engine.run_result.RunResult`."""
    rec: np.ndarray
    model: object                 # frogsim.engine.coupled.CoupledModel
    stats: dict = field(default_factory=dict)
    wall_s: float = 0.0           # [s] wall time of the steps (compilation excluded)
    compile_s: float = 0.0        # [s] compiling (or loading from the cache) the loop, before the steps
    python_law: object = None     # the Python function that drove the closed-loop muscles, if one did

    # -- what the shared methods read (frogsim.engine.run_result) ------------------------------
    @property
    def _circuit(self):
        return self.model.pneumatic

    @property
    def _laws(self) -> np.ndarray:
        return self.model.arrays["laws"]

    def _charge_valve(self, muscle: str) -> np.ndarray:
        return self.valves[:, CL.charge_valve(self.index(muscle))]

    @cached_property
    def switchings(self) -> dict:
        """{muscle: (charge valve switchings, discharge valve switchings)} of the muscles under a
        valve law (counted as the commands were applied)."""
        return valve_switchings(self._laws, self.muscle_names, self.model.arrays["cs"])

    def _clipped_samples(self, muscle: str) -> int:
        """Controller samples at which the joint-angle law of ``muscle``'s row clipped its pressure
        targets to [atmosphere, source]."""
        from frogsim.control.sampled import B_CLIPS, law_block
        cs = self.model.arrays["cs"]
        b = law_block(cs, self._rows_by_muscle()[muscle])
        return int(cs[b + B_CLIPS])

    # -- basic series ---------------------------------------------------------------------------
    @property
    def rs(self):
        return self.model.rs

    @property
    def t(self) -> np.ndarray:
        return self.rec[:, C.R_TIME]

    @property
    def muscle_names(self) -> list:
        return self.model.muscle_names

    @property
    def joint_names(self) -> list:
        return self.model.joint_names

    def _block(self, name: str) -> np.ndarray:
        return self.rec[:, self.model.columns[name]]

    @property
    def joint_angles(self) -> np.ndarray:
        """Joint angles [rad], shape (time, joint), 0 at the flexed stop (see joint_names)."""
        return self._block("angle")

    @property
    def joint_velocities(self) -> np.ndarray:
        return self._block("omega")

    @property
    def pressures(self) -> np.ndarray:
        """Muscle pressures [Pa abs], shape (time, muscle)."""
        return self._block("pressure")

    @property
    def lengths(self) -> np.ndarray:
        """Muscle lengths [m] (tendon length less the fittings)."""
        return self._block("length")

    @property
    def tensions(self) -> np.ndarray:
        """Muscle tensions [N]."""
        return self._block("tension")

    @property
    def charged(self) -> np.ndarray:
        """Air charged into each muscle since t = 0 [kg]."""
        return self._block("charged")

    def muscle_pressure(self, muscle: str) -> np.ndarray:
        """Pressure in a muscle [Pa abs]."""
        return self.pressures[:, self.index(muscle)]

    def charged_mass(self, muscle: str) -> np.ndarray:
        """Mass that has entered the muscle through its charge valve since t = 0 [kg]."""
        return self.charged[:, self.index(muscle)]

    @property
    def valves(self) -> np.ndarray:
        """Valve states (charge, discharge per muscle; 1 open), shape (time, 2 n)."""
        return self._block("valves")

    @property
    def palm_opening(self) -> np.ndarray:
        """Palm opening, 0 folded .. 1 open, shape (time, 2) (left, right)."""
        return self._block("palm")

    @property
    def position(self) -> np.ndarray:
        """Hull centre in the world [m], shape (time, 3)."""
        return self.rec[:, C.R_POSITION]

    @property
    def velocity(self) -> np.ndarray:
        """Velocity of the hull centre [m/s], shape (time, 3)."""
        return self.rec[:, C.R_VELOCITY]

    @property
    def heading(self) -> np.ndarray:
        """Heading of the hull (yaw) [rad]."""
        return self.rec[:, C.R_YAW]

    @property
    def thrust(self) -> np.ndarray:
        """The water's force on the legs along the hull's heading [N]."""
        return self.rec[:, C.R_THRUST]

    @property
    def hull_force(self) -> np.ndarray:
        """The water's force on the hull along its heading [N] (its drag when negative)."""
        return self.rec[:, C.R_HULL]

    @property
    def source_pressure(self) -> np.ndarray:
        return self.rec[:, C.R_PS]

    @property
    def exhaust_pressure(self) -> np.ndarray:
        return self.rec[:, C.R_PE]

    @property
    def total_air_mass(self) -> np.ndarray:
        """Air in source, exhaust and muscles [kg]: constant in the closed circuit."""
        return self.rec[:, C.R_AIR]

    @cached_property
    def forward(self) -> np.ndarray:
        """Forward displacement along the initial heading [m]."""
        h0 = self.heading[0]
        d = self.position[:, :2] - self.position[0, :2]
        return d[:, 0] * math.cos(h0) + d[:, 1] * math.sin(h0)

    @cached_property
    def forward_velocity(self) -> np.ndarray:
        """Velocity of the hull along its current heading [m/s]."""
        return self.velocity[:, 0] * np.cos(self.heading) + self.velocity[:, 1] * np.sin(self.heading)

    def contraction(self) -> np.ndarray:
        """Muscle contraction 1 - L/L0 [-], shape (time, muscle)."""
        L0 = self.model.pneumatic.mp[:, CL.M_L0]
        return 1.0 - self.lengths / L0[None, :]

    # -- phases ---------------------------------------------------------------------------------
    def extension_windows(self) -> list:
        """(start, end) [s] of the hip driving muscles' pressurise phase in every cycle."""
        from frogsim.control.gait import phase_windows
        return phase_windows(self.rs.gait, "drive", "hip")

    def _in_windows(self, windows) -> np.ndarray:
        t = self.t
        mask = np.zeros(t.size, bool)
        for a, b in windows:
            mask |= (t >= a) & (t < b)
        return mask

    def joint_delay(self, joint: str) -> float:
        """Time from the first charge command of the joint's driving muscle to the joint having
        moved 5 % of its excursion in that pressurise phase [s] (nan if it did not move)."""
        from frogsim.scenario.motion import command_time
        side = joint.split("_", 1)[1]
        base = joint.split("_", 1)[0]
        steps = self.rs.gait.joints[base]["drive"]
        charges = [t for t, s in steps if s == "charge"]
        if not charges:
            return float("nan")
        t_cmd = command_time(charges[0], self.rs.pneumatic.controller.rate)
        later = [t for t, s in steps if t > charges[0] and s != "charge"]
        t_end = later[0] if later else self.rs.gait.period
        t = self.t
        th = self.joint_angles[:, self.joint_names.index(joint)]
        k0 = int(np.searchsorted(t, t_cmd))
        k1 = int(np.searchsorted(t, t_end))
        seg = th[k0:k1] - th[k0]
        if seg.size < 2 or seg.max() <= 0.0:
            return float("nan")
        target = DELAY_FRACTION * seg.max()
        j = int(np.argmax(seg >= target))
        ta, tb, ya, yb = t[k0 + j - 1], t[k0 + j], seg[j - 1], seg[j]
        return float(ta + (target - ya) / (yb - ya) * (tb - ta) - t_cmd)

    # -- summary --------------------------------------------------------------------------------
    def summary(self) -> dict:
        """The headline figures, each key carrying its unit (see the module docstring)."""
        rs = self.rs
        gait = rs.gait
        T, N = gait.period, gait.cycles
        patm = self.atmospheric_pressure
        rho = self.reference_density
        t = self.t
        fwd = self.forward
        dist = float(fwd[-1])
        body_length = rs.robot.body.length
        cyc_end = [float(np.interp(k * T, t, fwd)) for k in range(N + 1)]
        per_cycle = [b - a for a, b in zip(cyc_end, cyc_end[1:])]
        ext = self.extension_windows()
        rec_windows = []
        for k in range(N):
            a, b = k * T, (k + 1) * T
            inside = sorted(w for w in ext if a <= w[0] < b)
            edges = [a] + [x for w in inside for x in w] + [b]
            rec_windows += [(edges[i], edges[i + 1]) for i in range(0, len(edges) - 1, 2)
                            if edges[i + 1] > edges[i]]
        m_ext, m_rec = self._in_windows(ext), self._in_windows(rec_windows)
        v = self.forward_velocity

        def mean_accel(windows):
            acc = [(np.interp(b, t, v) - np.interp(a, t, v)) / (b - a) for a, b in windows if b > a]
            return float(np.mean(acc)) if acc else float("nan")

        charged = float(self.rec[-1, C.R_CHARGED] - self.rec[0, C.R_CHARGED])
        exergy = float(self.rec[-1, C.R_EXERGY])
        mass = rs.layout.total_mass
        g = rs.robot.water.gravity
        st = self.model.arrays["st"]
        contraction = self.contraction()
        joints = {}
        for j, name in enumerate(self.joint_names):
            th = np.degrees(self.joint_angles[:, j])
            joints[name] = {"min_deg": float(th.min()), "max_deg": float(th.max()),
                            "range_limit_deg": math.degrees(rs.robot.joints[name.split("_")[0]].range),
                            "delay_s": self.joint_delay(name)}
        delays = [joints[n]["delay_s"] for n in self.joint_names]
        air_total = self.total_air_mass
        out = {
            "scenario": rs.name,
            "environment": rs.options.environment,
            "base": rs.options.base,
            "recovery": rs.options.recovery,
            "cycles": N,
            "period_s": T,
            "duration_s": float(t[-1]),
            "distance_m": dist,
            "mean_speed_m_per_s": dist / float(t[-1]),
            "mean_speed_body_lengths_per_s": dist / float(t[-1]) / body_length,
            "distance_per_cycle_m": dist / N,
            "distance_each_cycle_m": per_cycle,
            "thrust_peak_N": float(st[C.T_PEAK]),
            "thrust_peak_time_s": float(st[C.T_PEAK_TIME]),
            "thrust_peak_extension_N": float(np.max(self.thrust[m_ext])) if m_ext.any() else None,
            "thrust_mean_N": float(np.mean(self.thrust)),
            "thrust_mean_extension_N": float(np.mean(self.thrust[m_ext])) if m_ext.any() else None,
            "thrust_mean_recovery_N": float(np.mean(self.thrust[m_rec])) if m_rec.any() else None,
            "hull_force_mean_N": float(np.mean(self.hull_force)),
            "forward_acceleration_mean_extension_m_per_s2": mean_accel(ext),
            "forward_acceleration_mean_recovery_m_per_s2": mean_accel(rec_windows),
            "air_used_L_std": charged / rho * 1e3,
            "air_used_per_cycle_L_std": charged / rho * 1e3 / N,
            "pump_moved_L_std": float(self.rec[-1, C.R_PUMPED] / rho * 1e3),
            "source_pressure_initial_bar_gauge": float((self.source_pressure[0] - patm) / 1e5),
            "source_pressure_after_cycles_bar_gauge": float((self.source_pressure[-1] - patm) / 1e5),
            "source_pressure_each_cycle_start_bar_gauge": [float((np.interp(k * T, t, self.source_pressure) - patm)
                                                                 / 1e5) for k in range(N + 1)],
            "exhaust_pressure_after_cycles_bar_gauge": float((self.exhaust_pressure[-1] - patm) / 1e5),
            "air_exergy_J": exergy,
            "cost_of_transport": exergy / (mass * g * dist) if dist > 0 else None,
            "air_per_metre_L_std_per_m": charged / rho * 1e3 / dist if dist > 0 else None,
            "cost_of_transport_reason": None if dist > 0 else (f"not reached: no forward distance ({dist:.3g} m; "
                                                               f"base {rs.options.base!r})"),
            "robot_mass_with_ballast_kg": mass,
            "joint_delay_s": {n: joints[n]["delay_s"] for n in self.joint_names},
            "joint_delay_mean_s": float(np.nanmean(delays)) if np.isfinite(delays).any() else None,
            "joints": joints,
            "max_contraction_percent": {m: float(100 * contraction[:, i].max())
                                        for i, m in enumerate(self.muscle_names)},
            "aeration_volume_L_std": {m: self.aeration_volume(m) * 1e3 if len(self.charge_open_times(m)) else None
                                      for m in self.muscle_names},
            "air_mass_relative_drift": float(np.ptp(air_total) / air_total[0]),
            "solver": {**self.stats, "wall_time_s": self.wall_s, "compile_time_s": self.compile_s,
                       "real_time_factor": float(t[-1]) / self.wall_s if self.wall_s > 0 else None,
                       "timing_note": "wall_time_s and real_time_factor exclude compile_time_s"},
        }
        if self._rows_by_muscle():
            out["control"] = self.control_metrics()
        return out

    # -- table ----------------------------------------------------------------------------------
    def to_dataframe(self, units: str = "SI"):
        """All series as a pandas DataFrame, the unit in every column name.

        units="SI": [m], [m/s], [rad], [Pa abs], [N], [kg]; units="display": degrees, mm, bar
        gauge, litres at standard state, percent.
        """
        import pandas as pd
        if units not in ("SI", "display"):
            raise ValueError(f"units must be 'SI' or 'display', not {units!r}")
        disp = units == "display"
        patm, rho = self.atmospheric_pressure, self.reference_density
        cols = {"time_s": self.t}
        cols["x_m"], cols["y_m"] = self.position[:, 0], self.position[:, 1]
        cols["forward_distance_m"] = self.forward
        if disp:
            cols["heading_deg"] = np.degrees(self.heading)
        else:
            cols["heading_rad"] = self.heading
        cols["forward_velocity_m_per_s"] = self.forward_velocity
        cols["thrust_N"] = self.thrust
        cols["thrust_added_mass_N"] = self.rec[:, C.R_THRUST_AM]
        cols["hull_force_N"] = self.hull_force
        for name, p in (("source", self.source_pressure), ("exhaust", self.exhaust_pressure)):
            if disp:
                cols[f"{name}_pressure_bar_gauge"] = (p - patm) / 1e5
            else:
                cols[f"{name}_pressure_Pa_abs"] = p
        if disp:
            cols["air_charged_L_std"] = self.rec[:, C.R_CHARGED] / rho * 1e3
            cols["pump_moved_L_std"] = self.rec[:, C.R_PUMPED] / rho * 1e3
        else:
            cols["air_charged_kg"] = self.rec[:, C.R_CHARGED]
            cols["pump_moved_kg"] = self.rec[:, C.R_PUMPED]
        cols["pump_on"] = self.rec[:, C.R_PUMP_ON]
        for j, name in enumerate(self.joint_names):
            if disp:
                cols[f"{name}_angle_deg"] = np.degrees(self.joint_angles[:, j])
                cols[f"{name}_angular_velocity_deg_per_s"] = np.degrees(self.joint_velocities[:, j])
            else:
                cols[f"{name}_angle_rad"] = self.joint_angles[:, j]
                cols[f"{name}_angular_velocity_rad_per_s"] = self.joint_velocities[:, j]
        contraction = self.contraction()
        for i, name in enumerate(self.muscle_names):
            if disp:
                cols[f"{name}_pressure_bar_gauge"] = (self.pressures[:, i] - patm) / 1e5
                cols[f"{name}_length_mm"] = self.lengths[:, i] * 1e3
                cols[f"{name}_contraction_percent"] = 100 * contraction[:, i]
            else:
                cols[f"{name}_pressure_Pa_abs"] = self.pressures[:, i]
                cols[f"{name}_length_m"] = self.lengths[:, i]
            cols[f"{name}_tension_N"] = self.tensions[:, i]
            cols[f"{name}_charge_valve"] = self.valves[:, CL.charge_valve(i)]
            cols[f"{name}_discharge_valve"] = self.valves[:, CL.vent_valve(i)]
        for p, side in enumerate(("left", "right")):
            key = f"palm_{side}_opening_percent" if disp else f"palm_{side}_opening"
            cols[key] = self.palm_opening[:, p] * (100.0 if disp else 1.0)
        return pd.DataFrame(cols)


def as_robot_scenario(scenario, cycles: int | None = None):
    """A RobotScenario from a name, a TOML path, a dict or a RobotScenario (cycles override)."""
    from frogsim.robot.scenario import RobotScenario, load_robot_scenario
    if isinstance(scenario, RobotScenario):
        if cycles is None or cycles == scenario.gait.cycles:
            return scenario
        return load_robot_scenario({**scenario.raw, "base_dir": scenario.pneumatic.base_dir},
                                   cycles=cycles)
    return load_robot_scenario(scenario, cycles=cycles)


def swim(scenario, cycles: int | None = None, progress=None, controller=None) -> SwimResult:
    """Run a robot scenario (a shipped name such as "swim" or "leg-in-air", a TOML path, a dict
    or a RobotScenario) for ``cycles`` gait cycles (default: the scenario's) and return its result.

    ``controller``: a Python function ``fn(t, obs) -> {muscle: "charge" | "hold" | "vent"}``
    called at every controller sample instead of the compiled laws of the scenario's
    ``[controllers]`` (:func:`frogsim.engine.coupled_python.run_coupled_python`).

    Raises ScenarioError on bad input (before anything runs) and SimulationError, naming the
    quantity and the time, if the run goes unstable.
    """
    from frogsim.engine.coupled import build_coupled, run_coupled
    rs = as_robot_scenario(scenario, cycles)
    cm = build_coupled(rs)
    if controller is not None:
        from frogsim.engine.coupled_python import run_coupled_python
        out = run_coupled_python(cm, controller, progress=progress)
    else:
        out = run_coupled(cm, progress=progress)
    return SwimResult(rec=out["rec"], model=cm, stats=out["stats"], wall_s=out["wall_s"],
                      compile_s=out.get("compile_s", 0.0), python_law=controller)
