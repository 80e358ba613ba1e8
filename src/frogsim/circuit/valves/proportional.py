"""Valve type "proportional": a 5/3-way proportional directional valve (FESTO MPYE-5-1/8-HF class),
one per muscle.

One spool meters both paths of the muscle: its position x in -1..1 (the 0-10 V command V as
x = (V - signal_center) / signal_span; 5 V: mid position, both edges shut) opens the charge edge
(supply -> muscle) by x > 0 and the vent edge (muscle -> exhaust) by x < 0. Each edge is an ISO 6358
restriction (Eq. (8), :func:`frogsim.physics.flow.iso6358_mass_flow`) whose sonic conductance
grows with the edge's opening (:func:`frogsim.physics.flow.spool_conductance`: linear past the
overlap, the leakage when shut); the fully open conductance follows from the catalogue's standard
nominal flow (:func:`frogsim.physics.flow.sonic_conductance_from_nominal_flow`).

The spool follows its command as a first-order lag of time constant tau = 1/(2 pi f_c) (f_c the
-3 dB bandwidth). The driver holds the valve vector constant between its stops (each segment's
commands are constant), so the spool is not a state of the integrator: the controllers' view
(:func:`openings`) carries the spool's position from sample to sample (the valve's memory), and
over each controller period writes into the valve vector the spool's mean position over that
period under the held command (:func:`frogsim.physics.flow.spool_lag`, exact for the first-order
lag). The air each edge passes over a period is then exact where the conductance is linear in the
opening (past the overlap, on one side of the centre); what is approximated is the spool's motion
inside a period (at 1 kHz and 100 Hz, the period is 0.6 tau). The valve vector's two entries are
the two edges' openings: u[2i] = max(x, 0), u[2i+1] = max(-x, 0).

An open-loop program (charge / hold / vent) sets the openings 1 / 0 / 0 and 0 / 0 / 1 at once (no
spool lag); a closed-loop law's command goes through the lag.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from frogsim._jit import jit
from frogsim.circuit.layout import M_VP
from frogsim.circuit.valves.spec import ValveType
from frogsim.components.valves import MPYE_5_1_8_HF as CAT, value
from frogsim.errors import ScenarioError, Shown
from frogsim.physics.flow import iso6358_mass_flow, sonic_conductance_from_nominal_flow, spool_conductance, spool_lag
from frogsim.scenario.fields import quantity
from frogsim.scenario.schema import GAUGE_MAX, Valve
from frogsim.scenario.valves import ValveSettings

CODE = 2.0
#: the catalogue's gauge pressures are taken against the standard atmosphere [Pa]
NOMINAL_ATMOSPHERE = 101325.0

# the parameter block (offsets from M_VP)
P_C = 0         # sonic conductance of a fully open edge [m^3/(s Pa)]
P_B = 1         # critical ratio [-]
P_M = 2         # subsonic index [-]
P_RL = 3        # laminar ratio [-]
P_OVERLAP = 4   # overlap [-] (spool travel before an edge opens)
P_LEAK = 5      # an edge's conductance shut [m^3/(s Pa)]
P_TAU = 6       # the spool's time constant [s]


@dataclass(frozen=True)
class ProportionalValve(ValveSettings):
    """A 5/3-way proportional directional valve per muscle (its defaults: components/valves.py,
    each value with its source)."""
    TYPE: ClassVar[str] = "proportional"
    nominal_flow: float = quantity("volume_flow", gt=0.0, display="L/min", default=value(CAT, "nominal_flow"),
                                   doc="the catalogue's standard nominal flow (ANR) at the nominal conditions")
    nominal_inlet_gauge: float = quantity("pressure", gt=0.0, le=GAUGE_MAX, display="bar",
                                          default=value(CAT, "nominal_inlet_gauge"),
                                          doc="nominal flow's inlet pressure (gauge, against 101.325 kPa)")
    nominal_drop: float = quantity("pressure", gt=0.0, le=GAUGE_MAX, display="bar",
                                   default=value(CAT, "nominal_drop"), doc="nominal flow's pressure drop")
    critical_ratio: float = quantity("dimensionless", ge=0.0, lt=1.0, default=value(CAT, "critical_ratio"))
    subsonic_index: float = quantity("dimensionless", gt=0.0, le=1.0, default=0.5)
    laminar_ratio: float = quantity("dimensionless", gt=0.0, le=1.0, default=0.999)
    bandwidth: float = quantity("frequency", gt=0.0, le=10e3, display="Hz", default=value(CAT, "bandwidth"),
                                doc="the spool's -3 dB frequency (first-order lag, tau = 1/(2 pi f))")
    overlap: float = quantity("dimensionless", ge=0.0, lt=1.0, display="%", default=value(CAT, "overlap"),
                              doc="spool travel (fraction of full) before an edge opens")
    leakage_conductance: float = quantity("conductance", ge=0.0, display="L/(s*bar)",
                                          default=value(CAT, "leakage_conductance"),
                                          doc="each edge's sonic conductance when shut")
    dead_time: float = quantity("time", ge=0.0, le=1.0, display="ms", default=0.0,
                                doc="delay of a command before the spool starts to move")
    signal_center: float = quantity("voltage", ge=0.0, le=24.0, display="V", default=value(CAT, "signal_center"),
                                    doc="command voltage of the mid (shut) position")
    signal_span: float = quantity("voltage", gt=0.0, le=24.0, display="V", default=value(CAT, "signal_span"),
                                  doc="command voltage from the mid position to either end of travel")

    @property
    def sonic_conductance(self) -> float:
        """A fully open edge's sonic conductance [m^3/(s Pa)], from the nominal flow (Eq. (8) solved for C)."""
        p1 = NOMINAL_ATMOSPHERE + self.nominal_inlet_gauge
        return sonic_conductance_from_nominal_flow(self.nominal_flow, p1, p1 - self.nominal_drop,
                                                   self.critical_ratio, self.subsonic_index, self.laminar_ratio)

    @property
    def time_constant(self) -> float:
        """The spool's first-order time constant [s]: 1 / (2 pi bandwidth)."""
        return 1.0 / (2.0 * math.pi * self.bandwidth)

    @property
    def charge(self) -> Valve:
        """The charge edge fully open (what the engines and the laws read of every valve type)."""
        return Valve(sonic_conductance=self.sonic_conductance, critical_ratio=self.critical_ratio,
                     subsonic_index=self.subsonic_index, laminar_ratio=self.laminar_ratio, dead_time=self.dead_time)

    @property
    def discharge(self) -> Valve:
        """The vent edge fully open (the same spool and bore as the charge edge)."""
        return self.charge

    def volts(self, x):
        """The command voltage [V] of spool position(s) x [-]."""
        return self.signal_center + self.signal_span * x

    def check(self, path: str) -> None:
        if self.laminar_ratio <= self.critical_ratio:
            raise ScenarioError(f"{path}.laminar_ratio", self.laminar_ratio,
                                f"must exceed critical_ratio ({self.critical_ratio:g})")
        if self.nominal_drop >= NOMINAL_ATMOSPHERE + self.nominal_inlet_gauge:
            raise ScenarioError(f"{path}.nominal_drop", Shown(f"{self.nominal_drop / 1e5:g} bar"),
                                "must be below the nominal inlet's absolute pressure")
        if self.signal_span > self.signal_center:
            raise ScenarioError(f"{path}.signal_span", Shown(f"{self.signal_span:g} V"),
                                f"must not exceed signal_center ({self.signal_center:g} V): the command "
                                "voltage of full vent would be negative")


def block(v: ProportionalValve) -> tuple:
    return (v.sonic_conductance, v.critical_ratio, v.subsonic_index, v.laminar_ratio, v.overlap,
            v.leakage_conductance, v.time_constant)


@jit
def flows(mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref):
    """(charge, vent) mass flows [kg/s] through the spool's two edges at openings u_c, u_d: Eq. (8)
    with each edge's conductance at its opening; 0.0 through an edge of zero conductance."""
    C = mp[i, M_VP + P_C]
    b = mp[i, M_VP + P_B]
    m = mp[i, M_VP + P_M]
    rl = mp[i, M_VP + P_RL]
    ov = mp[i, M_VP + P_OVERLAP]
    leak = mp[i, M_VP + P_LEAK]
    mc = 0.0
    md = 0.0
    cc = spool_conductance(u_c, C, ov, leak)
    if cc > 0.0:
        mc = iso6358_mass_flow(p_up, T_up, p_i, T_i, cc, b, m, rl, rho_ref, T_ref)
    cd = spool_conductance(u_d, C, ov, leak)
    if cd > 0.0:
        md = iso6358_mass_flow(p_i, T_i, p_e, T_e, cd, b, m, rl, rho_ref, T_ref)
    return mc, md


@jit
def openings(mp, i, command, memory, dt):
    """The spool commanded to x_c = command (clipped to -1..1) for one period dt from its position
    ``memory``: the edges' openings at the period's mean position, and the position at its end."""
    xc = min(max(command, -1.0), 1.0)
    x_end, x_mean = spool_lag(memory, xc, dt, mp[i, M_VP + P_TAU])
    return max(x_mean, 0.0), max(-x_mean, 0.0), x_end


VALVE = ValveType(settings=ProportionalValve, code=CODE, block=block, flows=flows, openings=openings,
                  continuous=True)
