"""Valve type "switching": the paper's high-speed switching valves (FESTO MHJ9-LF), two per muscle.

A charge valve between the source and the muscle and a discharge valve between the muscle and the
exhaust, each open or shut: the valve vector's entry u[2i] (charge) or u[2i+1] (discharge) is
1 = open, 0 = shut (open above 0.5). An open valve passes the ISO 6358 flow of Eq. (8)
(:func:`frogsim.physics.flow.iso6358_mass_flow`) with its own sonic conductance C, critical ratio
b, subsonic index m and laminar ratio; its dead time (``[valves.charge] dead_time``) delays every
command (the controllers' queue, :mod:`frogsim.control.sampled`).

Settings: :class:`frogsim.scenario.schema.Valves` (``[valves.charge]``, ``[valves.discharge]``; it
stays in the scenario layer, where every scenario's type hints name it).
"""
from __future__ import annotations

from frogsim._jit import jit
from frogsim.circuit.layout import M_VP
from frogsim.circuit.valves.spec import ValveType
from frogsim.physics.flow import iso6358_mass_flow
from frogsim.scenario.schema import Valves

CODE = 1.0

# the parameter block (offsets from M_VP): each valve's ISO 6358 constants
P_CC = 0        # charge valve sonic conductance [m^3/(s Pa)]
P_CB = 1        # charge valve critical ratio [-]
P_CM = 2        # charge valve subsonic index [-]
P_CRL = 3       # charge valve laminar ratio [-]
P_DC = 4        # discharge valve: the same four
P_DB = 5
P_DM = 6
P_DRL = 7


def block(v: Valves) -> tuple:
    """The parameter block: the charge valve's C, b, m, r_lam, then the discharge valve's."""
    c, d = v.charge, v.discharge
    return (c.sonic_conductance, c.critical_ratio, c.subsonic_index, c.laminar_ratio,
            d.sonic_conductance, d.critical_ratio, d.subsonic_index, d.laminar_ratio)


@jit
def flows(mp, i, u_c, u_d, p_up, T_up, p_i, T_i, p_e, T_e, rho_ref, T_ref):
    """(charge, discharge) mass flows [kg/s] of muscle i's two valves: Eq. (8) through each open
    valve (u > 0.5), 0.0 through a shut one."""
    mc = 0.0
    md = 0.0
    if u_c > 0.5:
        mc = iso6358_mass_flow(p_up, T_up, p_i, T_i, mp[i, M_VP + P_CC], mp[i, M_VP + P_CB], mp[i, M_VP + P_CM],
                               mp[i, M_VP + P_CRL], rho_ref, T_ref)
    if u_d > 0.5:
        md = iso6358_mass_flow(p_i, T_i, p_e, T_e, mp[i, M_VP + P_DC], mp[i, M_VP + P_DB], mp[i, M_VP + P_DM],
                               mp[i, M_VP + P_DRL], rho_ref, T_ref)
    return mc, md


@jit
def openings(mp, i, command, memory, dt):
    """A mode (or the sign of a command): charge opens the charge valve, vent the discharge
    valve, hold (0) shuts both; no memory."""
    return (1.0 if command > 0 else 0.0), (1.0 if command < 0 else 0.0), memory


VALVE = ValveType(settings=Valves, code=CODE, block=block, flows=flows, openings=openings, continuous=False)
