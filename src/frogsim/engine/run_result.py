"""What a run's result is whatever engine made it: the part :class:`frogsim.Result` (the pneumatics
alone) and :class:`frogsim.engine.swim.SwimResult` (the robot in MuJoCo) share, written once.

:class:`RunResult` holds the methods whose meaning does not depend on the engine: the circuit's
constants (atmospheric pressure, reference density), a muscle's pressurise phases and the air it
took in the first (:meth:`RunResult.aeration_volume`), the closed-loop controllers' setpoints and
their metrics. :func:`control_metrics` is the one implementation of those metrics, one entry per
controller with one set of keys whatever the run (docs/metrics.md, "Controller metrics").

Each engine's result supplies its own records through a few members:

* ``t`` (output times [s]) and ``python_law`` (the Python function that drove the closed-loop
  muscles, or None);
* ``_circuit``: the run's :class:`frogsim.circuit.model.PneumaticModel` (its ``g``, ``names``,
  ``charge_open_times``, ``scenario``);
* ``_laws``: the table of laws the run was made with;
* ``switchings``: {muscle: (charge valve switchings, discharge valve switchings)} of the muscles
  under a valve law, counted as the commands were applied (:func:`valve_switchings`);
* ``muscle_pressure(muscle)`` [Pa abs], ``charged_mass(muscle)`` [kg since t = 0] and
  ``_charge_valve(muscle)`` (the charge valve's state, 1 = open), each on the output times;
* a robot run also ``joint_angles`` (time, joint) [rad], ``joint_names`` and
  ``_clipped_samples(muscle)`` (the joint-angle law's count of clipped pressure targets).

Both also give ``source_pressure``, ``exhaust_pressure`` [Pa abs], ``total_air_mass`` [kg] and
``lengths`` [m] from their own records (the pneumatic run's state, the robot's record columns).
"""
from __future__ import annotations

import numpy as np

from frogsim.circuit import layout as L


def valve_switchings(laws, names, cs) -> dict:
    """{muscle: (charge valve switchings, discharge valve switchings)} of the muscles under a
    valve law of the table ``laws``, from the controllers' final state ``cs`` (exact: counted as
    the commands are applied, not read off the output grid); ``names``: the muscles in the
    model's order."""
    from frogsim.control.sampled import L_MUSCLE, switch_counts
    counts = switch_counts(laws, cs)
    return {names[int(laws[c, L_MUSCLE])]: v for c, v in counts.items()}


def label_and_setpoint(ctl, law, t: np.ndarray, own) -> tuple:
    """(the label, the setpoint on the output times or None) a controller's metrics carry.

    The scenario's controller ``ctl`` is labelled with its kind and measured against its own
    setpoint (``own()``, when it has one); a run driven by a Python ``law`` instead is labelled
    with the law's ``label`` attribute (else "python:" and its name) and measured against the
    law's ``setpoint`` attribute (a function of t [s], in the controller's unit), or nothing."""
    if law is None:
        return ctl.kind, (own() if ctl.setpoint is not None else None)
    label = getattr(law, "label", None) or f"python:{getattr(law, '__name__', type(law).__name__)}"
    fn = getattr(law, "setpoint", None)
    return label, (None if fn is None else np.array([fn(float(x)) for x in t], float))


def _rms_max(e: np.ndarray, scale: float) -> tuple:
    """(RMS, largest magnitude) of the errors ``e`` divided by ``scale``; (None, None) if empty."""
    if not e.size:
        return None, None
    return float(np.sqrt(np.mean(e ** 2)) / scale), float(np.max(np.abs(e)) / scale)


def control_metrics(run) -> dict:
    """{controller name: its metrics} for every closed-loop controller of ``run`` (a
    :class:`RunResult`), the same keys for a pneumatic run and a robot run (docs/metrics.md,
    "Controller metrics"):

    * ``kind``: the controller's kind (or the Python law's label);
    * ``muscles``: the muscles whose valves it drives; ``joint``: the joint it tracks (joint-angle);
    * ``settle_s`` and the tracking error from then on, on the output grid, against the true
      signal: ``tracking_error_rms_bar``, ``tracking_error_max_bar`` (a pressure controller: the
      muscle's pressure) or ``tracking_error_rms_deg``, ``tracking_error_max_deg`` (a joint-angle
      controller: the joint's angle); absent when there is no setpoint to track;
    * ``samples_pressure_target_clipped`` (joint-angle): controller samples at which the pair's
      pressure targets were clipped to [atmosphere, source];
    * ``switchings``: {muscle: {"charge": n, "discharge": n}}, each valve's state changes as
      applied; ``switchings_per_s``: their sum over the run's duration (None for a run of one row);
    * ``air_used_L_std``: air that entered its muscles through their charge valves [L standard].
    """
    from frogsim.control import kinds
    sc = run._circuit.scenario
    t = run.t
    T = float(t[-1] - t[0]) if t.size > 1 else 0.0
    rho = run.reference_density
    counts = run.switchings
    out = {}
    for name, ctl in sc.controllers.items():
        if not ctl.closed_loop:
            continue
        muscles = list(ctl.driven())
        declared = kinds.of(ctl)
        angle = declared.tracks == "angle"      # the controller tracks its joint's angle
        label, sp = label_and_setpoint(ctl, run.python_law, t, lambda name=name: run.setpoint(name))
        entry = {"kind": label, "muscles": muscles}
        if angle:
            entry["joint"] = ctl.joint
        if sp is not None:
            settle = ctl.settle_time(sc.duration)
            after = t >= settle
            entry["settle_s"] = settle
            if angle:
                e = np.degrees(sp - run.joint_angles[:, run.joint_names.index(ctl.joint)])[after]
                entry["tracking_error_rms_deg"], entry["tracking_error_max_deg"] = _rms_max(e, 1.0)
            else:
                e = (sp - run.muscle_pressure(ctl.muscle))[after]
                entry["tracking_error_rms_bar"], entry["tracking_error_max_bar"] = _rms_max(e, 1e5)
        if "samples_pressure_target_clipped" in declared.metrics:
            entry["samples_pressure_target_clipped"] = run._clipped_samples(ctl.muscle)
        sw = {mu: dict(zip(("charge", "discharge"), counts.get(mu, (0, 0)))) for mu in muscles}
        entry["switchings"] = sw
        total = sum(v["charge"] + v["discharge"] for v in sw.values())
        entry["switchings_per_s"] = total / T if T > 0 else None
        charged = sum(float(run.charged_mass(mu)[-1] - run.charged_mass(mu)[0]) for mu in muscles)
        entry["air_used_L_std"] = charged / rho * 1e3
        out[name] = entry
    return out


class RunResult:
    """The methods a pneumatic run's and a robot run's results share (see the module docstring for
    what each engine's result supplies)."""

    # -- the circuit --------------------------------------------------------------------------
    @property
    def atmospheric_pressure(self) -> float:
        """The atmosphere's pressure [Pa abs] (gauge = absolute - this)."""
        return float(self._circuit.g[L.G_PATM])

    @property
    def reference_density(self) -> float:
        """Air's density at the ISO 8778 standard state [kg/m^3]: mass / this = standard volume."""
        return float(self._circuit.g[L.G_RHOREF])

    def index(self, muscle: str) -> int:
        """The muscle's position in the model's order (KeyError naming the muscles if none)."""
        try:
            return self._circuit.names.index(muscle)
        except ValueError:
            raise KeyError(f"no muscle {muscle!r}; muscles: {', '.join(self._circuit.names)}") from None

    # -- pressurise phases --------------------------------------------------------------------
    def charge_open_times(self, muscle: str) -> np.ndarray:
        """Times at which the muscle's charge valve actually opens [s] (command + dead time)."""
        return self._circuit.charge_open_times[self.index(muscle)]

    def _phase(self, muscle: str, stroke: int):
        """(charge-valve state (1, T), opening time (1,)) of one pressurise phase."""
        opens = self.charge_open_times(muscle)
        if stroke >= len(opens):
            raise IndexError(f"muscle {muscle!r} has {len(opens)} pressurise phases")
        return self._charge_valve(muscle)[None, :], np.array([opens[stroke]])

    def aeration_volume(self, muscle: str, stroke: int = 0) -> float:
        """Standard volume [m^3] (ISO 8778) charged into the muscle during one pressurise phase.

        The paper's aeration volume (Sec. 4.2): the flow of Eq. (8) integrated while the charge
        valve is open, expressed at the standard state. IndexError when the muscle has no such
        phase (:meth:`charge_open_times`).
        """
        from frogsim.engine.measures import charged_in_phase
        u, t_open = self._phase(muscle, stroke)
        q = charged_in_phase(self.t, self.charged_mass(muscle)[None, :], u, t_open)
        return float(q[0] / self.reference_density)

    # -- closed-loop control (docs/control.md, docs/metrics.md) --------------------------------
    def _rows_by_muscle(self) -> dict:
        """{muscle: its row in the run's table of laws} of the muscles under a valve law."""
        from frogsim.control.sampled import L_KIND, L_MUSCLE, KIND_PUMP_BAND
        laws = self._laws
        if laws.ndim == 1:
            return {}
        return {self._circuit.names[int(laws[c, L_MUSCLE])]: c for c in range(laws.shape[0])
                if laws[c, L_KIND] != KIND_PUMP_BAND}

    def _law_rows(self) -> dict:
        """{controller name: the row of its (first) muscle in the table of laws} of the closed-loop
        controllers."""
        rows = self._rows_by_muscle()
        return {name: rows[ctl.muscle] for name, ctl in self._circuit.scenario.controllers.items()
                if ctl.closed_loop and ctl.muscle in rows}

    def setpoint(self, controller: str) -> np.ndarray:
        """A closed-loop controller's setpoint at the output times: [Pa abs] for a pressure
        controller, [rad] for a joint-angle controller; NaN for one without a setpoint (open-loop
        PWM)."""
        from frogsim.control.sampled import setpoint
        rows = self._law_rows()
        if controller not in rows:
            raise KeyError(f"no closed-loop controller {controller!r}; controllers: {', '.join(rows) or 'none'}")
        ctl = self._circuit.scenario.controllers[controller]
        if ctl.setpoint is None:
            return np.full(self.t.size, np.nan)
        laws, c = self._laws, rows[controller]
        return np.array([setpoint(laws, c, float(t))[0] for t in self.t])

    def control_metrics(self) -> dict:
        """Per closed-loop controller: tracking error, valve switchings, air used
        (:func:`control_metrics`; docs/metrics.md, "Controller metrics")."""
        return control_metrics(self)

    def _clipped_samples(self, muscle: str) -> int:
        raise NotImplementedError("only a robot run has joint-angle controllers")
