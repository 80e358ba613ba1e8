"""Result of a run: time series on the output grid, data first; tables and plots are made from it."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from frogsim.circuit import layout as L
from frogsim.engine.measures import RiseTimes, fraction_of_window, pressurise_window, rise_times, value_at_close
from frogsim.engine.run_result import RunResult


@dataclass
class Result(RunResult):
    """Time series of one pneumatic run (SI inside).

    Attributes: ``t`` [s], ``y`` (state at each output time, see :mod:`frogsim.circuit.layout`),
    ``u`` (valve states and pump state at each output time), ``model`` (the built model), ``status``
    ("ok"), ``stats`` (accepted steps, rejected steps, right-hand-side evaluations).

    What it shares with a robot run's result (the circuit's constants, aeration volume, setpoints,
    the controllers' metrics) is written once in :class:`frogsim.engine.run_result.RunResult`.
    """
    t: np.ndarray
    y: np.ndarray
    u: np.ndarray
    model: object
    stats: dict = field(default_factory=dict)
    status: str = "ok"
    switchings: dict = field(default_factory=dict)   # closed-loop muscles: (charge, discharge) valve switchings
    python_law: object = None      # the Python function that drove the closed-loop muscles, if one did

    # -- what the shared methods read (frogsim.engine.run_result) ------------------------------
    @property
    def _circuit(self):
        return self.model

    @property
    def _laws(self) -> np.ndarray:
        return self.model.laws

    def _charge_valve(self, muscle: str) -> np.ndarray:
        return self.u[:, L.charge_valve(self.index(muscle))]

    # -- basic series -------------------------------------------------------------------------
    @property
    def names(self) -> list:
        return self.model.names

    @property
    def n(self) -> int:
        return len(self.model.names)

    @property
    def source_pressure(self) -> np.ndarray:
        """Source chamber pressure [Pa abs]."""
        return self.y[:, L.Y_PS]

    @property
    def exhaust_pressure(self) -> np.ndarray:
        """Exhaust chamber pressure [Pa abs]."""
        return self.y[:, L.Y_PE]

    def muscle_pressure(self, muscle: str) -> np.ndarray:
        """Pressure in a muscle [Pa abs]."""
        return self.y[:, L.pressure_index(self.index(muscle))]

    def muscle_mass(self, muscle: str) -> np.ndarray:
        """Air mass in a muscle [kg]."""
        return self.y[:, L.mass_index(self.index(muscle))]

    def charged_mass(self, muscle: str) -> np.ndarray:
        """Mass that has entered the muscle through its charge valve since t = 0 [kg]."""
        return self.y[:, L.charged_index(self.index(muscle), self.n)]

    def vented_mass(self, muscle: str) -> np.ndarray:
        """Mass that has left the muscle through its discharge valve since t = 0 [kg]."""
        return self.y[:, L.vented_index(self.index(muscle), self.n)]

    @property
    def pumped_mass(self) -> np.ndarray:
        """Mass moved by the pump from exhaust to source since t = 0 [kg]."""
        return self.y[:, L.pump_index(self.n)]

    @property
    def total_air_mass(self) -> np.ndarray:
        """Air in source, exhaust and all muscles [kg]: constant in the closed circuit."""
        return self.y[:, L.Y_MS] + self.y[:, L.Y_ME] + self.y[:, L.mass_slice(self.n)].sum(axis=1)

    def temperature(self, which: str) -> np.ndarray:
        """Temperature [K] of "source", "exhaust" or a muscle, from T = p V/(m R)."""
        R = self.model.g[L.G_R]
        if which == "source":
            return self.y[:, L.Y_PS] * self.model.g[L.G_VS] / (self.y[:, L.Y_MS] * R)
        if which == "exhaust":
            return self.y[:, L.Y_PE] * self.model.g[L.G_VE] / (self.y[:, L.Y_ME] * R)
        i = self.index(which)
        return self.muscle_pressure(which) * self.volumes[:, i] / (self.muscle_mass(which) * R)

    @cached_property
    def _diagnostics(self):
        """(flows (time, 2n+1) [kg/s], volumes (time, n) [m^3], lengths (time, n) [m]).

        Calls the engine's compiled right-hand side at each output point from Python (a few ms
        per thousand points), which avoids compiling a second copy of it; the volumes and lengths
        are the ones it leaves in its scratch ``work`` (:mod:`frogsim.circuit.rhs`).
        """
        from frogsim.circuit.rhs import rhs
        m = self.model
        n = self.n
        nt = self.t.size
        flows = np.empty((nt, L.flows_size(n)))
        V = np.empty((nt, n))
        Lm = np.empty((nt, n))
        dydt = np.empty(self.y.shape[1])
        work = np.zeros(L.work_size(n))
        args = (m.g, m.mp, m.mot_t, m.mot_L, m.mot_d, m.mot_n)
        valves, pump = L.valve_slice(n), L.pump_entry(n)
        for k in range(nt):
            u = np.ascontiguousarray(self.u[k, valves])
            rhs(float(self.t[k]), np.ascontiguousarray(self.y[k]), u, float(self.u[k, pump]),
                *args, dydt, flows[k], work)
            V[k] = work[L.work_slice(L.WORK_V, n)]
            Lm[k] = work[L.work_slice(L.WORK_L, n)]
        return flows, V, Lm

    @property
    def volumes(self) -> np.ndarray:
        """Muscle volumes [m^3], shape (time, muscle)."""
        return self._diagnostics[1]

    @property
    def lengths(self) -> np.ndarray:
        """Muscle lengths [m], shape (time, muscle)."""
        return self._diagnostics[2]

    def tensions(self, law=None) -> np.ndarray:
        """Muscle tensions [N], shape (time, muscle), from the force law at the output points'
        pressures and lengths (the pneumatic engine moves the muscles along their paths; the force
        does not act back on them).

        ``law``: a :class:`frogsim.robot.params.MuscleForceLaw`; default: the scenario's parameter
        set's ``[muscle_force]`` (with the scenario's own settings over it). With its hysteresis
        on, each muscle's slip elements start relaxed at its first contraction and follow its
        length path exactly: between two output points they are also taken through every point
        where the path may turn (:func:`frogsim.circuit.rhs.length_turning_times`: its knots and
        the roots of dL/dt), so a turning point between samples is not cut off (the model is rate
        independent: only the path's turning points matter).
        """
        from frogsim.circuit.rhs import length_turning_times, motion_length
        from frogsim.physics.hysteresis import element_table, maxwell_slip_force
        from frogsim.robot.params import parameter_set_law
        from frogsim.circuit import actuators
        from frogsim.physics.muscle_force import hysteretic_tension
        law = law if law is not None else parameter_set_law(self.model.scenario)
        sc = self.model.scenario
        block = np.array(actuators.force_block([sc.muscle_types[sc.muscles[m].type] for m in self.names], law))
        mp = self.model.mp
        patm = self.atmospheric_pressure
        out = np.empty((self.t.size, self.n))
        motion = (self.model.mot_t, self.model.mot_L, self.model.mot_d, self.model.mot_n)
        elements = None if law.hysteresis == "none" else element_table(
            law.slip_elements, law.slip_per_pressure, law.slip_strain)
        for i, name in enumerate(self.names):
            p = self.muscle_pressure(name) - patm
            Lm = self.lengths[:, i]
            L0 = mp[i, L.M_L0]
            anchors = None if elements is None else np.full(elements[0].size, 1.0 - Lm[0] / L0)
            turns = None if elements is None else length_turning_times(i, *motion)
            for k in range(self.t.size):
                f = actuators.force(mp, i, float(p[k]), float(Lm[k]), block)
                if anchors is not None:
                    if k > 0:
                        for tt in turns[(turns > self.t[k - 1]) & (turns < self.t[k])]:
                            Lt, _ = motion_length(float(tt), i, *motion)
                            maxwell_slip_force(1.0 - Lt / L0, anchors, *elements)
                    f = hysteretic_tension(f, float(p[k]), 1.0 - float(Lm[k]) / L0, anchors, *elements)
                out[k, i] = f
        return out

    def charge_flow(self, muscle: str) -> np.ndarray:
        """Mass flow through the muscle's charge valve [kg/s] (negative: back to the source)."""
        return self._diagnostics[0][:, L.charge_valve(self.index(muscle))]

    def discharge_flow(self, muscle: str) -> np.ndarray:
        """Mass flow through the muscle's discharge valve [kg/s]."""
        return self._diagnostics[0][:, L.vent_valve(self.index(muscle))]

    @property
    def pump_flow(self) -> np.ndarray:
        """Pump mass flow [kg/s]."""
        return self._diagnostics[0][:, L.pump_entry(self.n)]

    # -- derived figures -------------------------------------------------------------------------
    def rise(self, muscle: str, fraction: float = 0.9, stroke: int = 0) -> RiseTimes:
        """The full rise-time measurement of one pressurise phase (time, start and target
        pressures, level, fraction of the rise reached, status, reason): see
        :mod:`frogsim.engine.measures` and docs/metrics.md."""
        u, t_open = self._phase(muscle, stroke)
        return rise_times(self.t, self.muscle_pressure(muscle)[None, :], self.source_pressure[None, :],
                          u, t_open, fraction)

    def rise_time(self, muscle: str, fraction: float = 0.9, stroke: int = 0) -> float:
        """Time [s] from the charge valve opening (command + dead time) until the muscle pressure
        first reaches p_start + fraction (p_target - p_start), p_target being the source pressure
        when the valve closes (the pressure the muscle settles to). NaN when the muscle does not
        get there while the valve is open; :meth:`rise_time_reason` says why."""
        return float(self.rise(muscle, fraction, stroke).seconds[0])

    def rise_time_reason(self, muscle: str, fraction: float = 0.9, stroke: int = 0) -> str | None:
        """Why :meth:`rise_time` is NaN (e.g. "not reached before the charge valve closed (reached
        53 % of the rise, needs 90 %)"); None when it is a number."""
        return self.rise(muscle, fraction, stroke).reason(0)

    def branch_limited_fraction(self, muscle: str, stroke: int = 0, until: str = "phase") -> float:
        """Fraction of time during which the Eq. (9) per-branch limit (``supply.mode = "paper"``)
        capped the muscle's charge flow; 0 in the other modes.

        ``until="phase"``: over the pressurise phase (valve opening to close); ``until="rise"``:
        over the rise, from the opening until the 90 % rise level is reached (to the close if it
        is not). Exact on the output grid: the engine clips the valve's flow to the limit, so the
        flow equals the limit exactly while the cap binds (evaluated at each output point by the
        engine's own right-hand side)."""
        if until not in ("phase", "rise"):
            raise ValueError(f"until must be 'phase' or 'rise', not {until!r}")
        if int(self.model.g[L.G_SUPPLY_MODE]) != L.SUPPLY_PAPER:
            return 0.0
        u, t_open = self._phase(muscle, stroke)
        limit = float(self.model.g[L.G_BRANCH_LIMIT])
        capped = np.abs(self.charge_flow(muscle)) >= limit * (1.0 - 1e-9)
        _, t_close = self.pressurise_window(muscle, stroke)
        t_end = t_close
        if until == "rise":
            rt = self.rise_time(muscle, 0.9, stroke)
            if np.isfinite(rt):
                t_end = t_open[0] + rt
        return float(fraction_of_window(self.t, capped[None, :], t_open, np.array([t_end]))[0])

    def pressurise_window(self, muscle: str, stroke: int = 0) -> tuple[float, float]:
        """(time the charge valve opens, first output time it is closed again) [s]; the end of
        the run if it never closes (see :func:`frogsim.engine.measures.pressurise_window`)."""
        u, t_open = self._phase(muscle, stroke)
        _, k_closed, _ = pressurise_window(self.t, u, t_open)
        return float(t_open[0]), float(self.t[k_closed[0]])

    def pressure_at_close(self, muscle: str, stroke: int = 0) -> float:
        """Muscle pressure [Pa abs] at the last output point with the charge valve open."""
        u, t_open = self._phase(muscle, stroke)
        return float(value_at_close(self.t, self.muscle_pressure(muscle)[None, :], u, t_open)[0])

    # -- tables ----------------------------------------------------------------------------------
    def to_dataframe(self, units: str = "SI"):
        """All series as a pandas DataFrame.

        units="SI": pressures [Pa abs], temperatures [K], volumes [m^3], lengths [m], mass flows
        [kg/s], masses [kg]; units="display": bar gauge, cm^3, mm, L/min and L at standard state
        (ISO 8778). Column names carry the unit; ``df.attrs["units"]`` maps each column to it.
        """
        import pandas as pd
        if units not in ("SI", "display"):
            raise ValueError(f"units must be 'SI' or 'display', not {units!r}")
        patm = self.atmospheric_pressure
        rho = self.reference_density
        cols, unit_of = {}, {}

        def put(name, values, unit):
            cols[name] = np.asarray(values, float)
            unit_of[name] = unit

        disp = units == "display"
        put("time_s", self.t, "s")
        series = [("source", self.source_pressure), ("exhaust", self.exhaust_pressure)]
        for who, p in series:
            if disp:
                put(f"{who}_pressure_bar_gauge", (p - patm) / 1e5, "bar (gauge)")
                put(f"{who}_temperature_K", self.temperature(who), "K")
            else:
                put(f"{who}_pressure_Pa_abs", p, "Pa (absolute)")
                put(f"{who}_temperature_K", self.temperature(who), "K")
                put(f"{who}_mass_kg", self.y[:, L.Y_MS if who == "source" else L.Y_ME], "kg")
        put("pump_on", self.u[:, L.pump_entry(self.n)], "1 = running")
        if disp:
            put("pump_flow_L_per_min_std", self.pump_flow / rho * 6e4, "L/min (standard)")
        else:
            put("pump_flow_kg_per_s", self.pump_flow, "kg/s")
        for i, m in enumerate(self.names):
            p = self.muscle_pressure(m)
            if disp:
                put(f"{m}_pressure_bar_gauge", (p - patm) / 1e5, "bar (gauge)")
                put(f"{m}_temperature_K", self.temperature(m), "K")
                put(f"{m}_volume_cm3", self.volumes[:, i] * 1e6, "cm^3")
                put(f"{m}_length_mm", self.lengths[:, i] * 1e3, "mm")
                put(f"{m}_charge_flow_L_per_min_std", self.charge_flow(m) / rho * 6e4, "L/min (standard)")
                put(f"{m}_discharge_flow_L_per_min_std", self.discharge_flow(m) / rho * 6e4,
                    "L/min (standard)")
                put(f"{m}_charged_L_std", self.charged_mass(m) / rho * 1e3, "L (standard)")
            else:
                put(f"{m}_pressure_Pa_abs", p, "Pa (absolute)")
                put(f"{m}_temperature_K", self.temperature(m), "K")
                put(f"{m}_mass_kg", self.muscle_mass(m), "kg")
                put(f"{m}_volume_m3", self.volumes[:, i], "m^3")
                put(f"{m}_length_m", self.lengths[:, i], "m")
                put(f"{m}_charge_flow_kg_per_s", self.charge_flow(m), "kg/s")
                put(f"{m}_discharge_flow_kg_per_s", self.discharge_flow(m), "kg/s")
                put(f"{m}_charged_mass_kg", self.charged_mass(m), "kg")
            put(f"{m}_charge_valve", self.u[:, L.charge_valve(i)], "1 = open")
            put(f"{m}_discharge_valve", self.u[:, L.vent_valve(i)], "1 = open")
        df = pd.DataFrame(cols)
        df.attrs["units"] = unit_of
        return df

