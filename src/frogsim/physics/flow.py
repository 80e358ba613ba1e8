"""Flow through valves, tubes and the micro pump (paper Sec. 3.3, Eqs. (8) and (9)).

Flows are mass flows [kg/s] inside; "standard" volume flows (ANR, ISO 8778: 100 kPa, 293.15 K)
are mass flows divided by the reference density rho_ref.
"""
from __future__ import annotations

import math

from frogsim._jit import jit, jit_step

from frogsim.physics.air import choked_mass_flux_factor


@jit
def iso6358_flow_function(sigma: float, b: float, m: float, r_lam: float) -> float:
    """The dimensionless factor omega(sigma) of Eq. (8), with the ISO 6358-1:2013 options  [-].

    * choked,    sigma <= b:          omega = 1
    * subsonic,  b < sigma <= r_lam:  omega = [1 - ((sigma - b)/(1 - b))^2]^m
    * laminar,   r_lam < sigma <= 1:  omega = (1 - sigma)/(1 - r_lam) * omega(r_lam)

    The paper's Eq. (8) is m = 0.5 and r_lam = 1 (no laminar region). ISO 6358-1:2013 adds the
    subsonic index m and a laminar region near sigma = 1 (r_lam typically 0.995..0.999), which makes
    the flow linear in the pressure difference there instead of having an infinite slope.
    omega is continuous at sigma = b and at sigma = r_lam, and zero at sigma = 1.

    Worked number: b = 0.38, sigma = 0.69, m = 0.5 gives omega = sqrt(1 - 0.25) = 0.866.
    """
    if sigma <= b:
        return 1.0
    if sigma >= 1.0:
        return 0.0
    if sigma > r_lam:
        x = (r_lam - b) / (1.0 - b)
        return (1.0 - sigma) / (1.0 - r_lam) * _power(1.0 - x * x, m)
    x = (sigma - b) / (1.0 - b)
    return _power(1.0 - x * x, m)


@jit_step
def _power(x: float, m: float) -> float:
    """x**m, with the usual m = 0.5 (Eq. (8)'s square root) taken by sqrt, several times faster."""
    if m == 0.5:
        return math.sqrt(x)
    return x ** m


@jit
def iso6358_mass_flow(p_a: float, T_a: float, p_b: float, T_b: float, C: float, b: float,
                      m: float, r_lam: float, rho_ref: float, T_ref: float) -> float:
    """Eq. (8): ISO 6358 mass flow through a restriction from side a to side b  [kg/s].

        Q = C p1 sqrt(T_ref/T1) omega(p2/p1, b)       (standard volume flow, m^3/s)
        m_dot = rho_ref Q

    The upstream side is whichever pressure is higher; the result is positive from a to b and
    negative for flow from b to a, with the upstream temperature of the side it leaves.

    Args:
        p_a, p_b: absolute pressures [Pa]; T_a, T_b: temperatures [K].
        C: sonic conductance [m^3/(s Pa)] (0.4 L/(s bar) = 4e-9 m^3/(s Pa) for the MHJ9 valve).
        b: critical pressure ratio [-]; m: subsonic index [-]; r_lam: laminar pressure ratio [-].
        rho_ref, T_ref: ISO reference density [kg/m^3] and temperature [K].

    Worked number: MHJ9 (C = 0.4 L/(s bar), b = 0.38) choked from 7.013 bar abs at 293.15 K passes
    0.4 * 7.013 = 2.805 L/s = 168.3 L/min standard.
    """
    if p_a >= p_b:
        return C * rho_ref * p_a * math.sqrt(T_ref / T_a) * iso6358_flow_function(p_b / p_a, b, m, r_lam)
    return -C * rho_ref * p_b * math.sqrt(T_ref / T_b) * iso6358_flow_function(p_a / p_b, b, m, r_lam)


@jit
def main_pipe_branch_limit(inner_diameter: float, velocity: float, n_tubes: float,
                           n_branches: float) -> float:
    """Eq. (9): Q = pi r^2 v; the main pipe's flow shared evenly by its branches  [m^3/s standard].

    The paper evaluates Q at the sonic velocity and reads it as a standard (atmospheric-density)
    volume flow divided over six branches: a 4 mm bore at 343.2 m/s carries 258.8 L/min, i.e.
    43.1 L/min per branch (the paper rounds to 45 L/min).
    """
    r = 0.5 * inner_diameter
    return math.pi * r * r * velocity * n_tubes / n_branches


@jit
def tube_sonic_conductance(inner_diameter: float, discharge_coefficient: float, R: float,
                           k: float, rho_ref: float, T_ref: float) -> float:
    """Sonic conductance of a tube bore taken as an isentropic nozzle  [m^3/(s Pa)].

    Equates the ideal choked flow C_d A p1 psi/sqrt(T1) with ISO 6358's C rho_ref p1 sqrt(T_ref/T1):
    C = C_d A psi / (rho_ref sqrt(T_ref)). With real upstream density this flow grows with p1; a
    4 mm bore (C_d = 1) passes about 1050 L/min standard at 7 bar abs, four times Eq. (9)'s value.
    Its critical ratio is the isentropic one, :func:`frogsim.physics.air.critical_pressure_ratio`.
    """
    area = math.pi * 0.25 * inner_diameter * inner_diameter
    return discharge_coefficient * area * choked_mass_flux_factor(R, k) / (rho_ref * math.sqrt(T_ref))


@jit
def pump_mass_flow(p_in: float, T_in: float, p_out: float, displacement: float,
                   max_ratio: float, R: float) -> float:
    """Micro pump from the exhaust (inlet) to the source (outlet)  [kg/s].

    A displacement pump whose volumetric efficiency falls linearly with the pressure ratio
    r = p_out/p_in, from 1 at r <= 1 to 0 at the stall ratio r_max:

        m_dot = rho_in * V_disp * clip(1 - (r - 1)/(r_max - 1), 0, 1)

    Args: p_in, p_out [Pa abs]; T_in [K]; displacement: free-air volume flow at r = 1 [m^3/s];
    max_ratio: stall pressure ratio [-]; R [J/(kg K)].
    """
    r = p_out / p_in
    eff = 1.0 - (r - 1.0) / (max_ratio - 1.0)
    if eff > 1.0:
        eff = 1.0
    elif eff < 0.0:
        eff = 0.0
    return p_in / (R * T_in) * displacement * eff


# --- proportional (spool) valves ------------------------------------------------------------------------
@jit
def spool_conductance(opening: float, C_max: float, overlap: float, C_leak: float) -> float:
    """Sonic conductance of one metering edge of a spool valve at spool opening ``opening``  [m^3/(s Pa)].

        C(a) = C_leak + (C_max - C_leak) clip((a - a_o) / (1 - a_o), 0, 1)

    a in [0, 1] is the spool's travel towards this edge (1: fully open), a_o the overlap (the
    travel before the edge starts to open: 0 for a critical-centre spool), C_leak the edge's
    conductance shut (leakage past the lands). Assumes the metering area, and with it the ISO 6358
    conductance, grows linearly with the travel past the overlap (rectangular ports; the critical
    ratio b of the fully open edge kept at every opening).

    Worked numbers: C_max = 2.8 L/(s bar), no overlap, no leak: a = 0.25 gives 0.7 L/(s bar); with
    a_o = 0.1, a = 0.1 gives C_leak exactly and a = 1 gives C_max exactly.
    """
    x = (opening - overlap) / (1.0 - overlap)
    if x <= 0.0:
        return C_leak
    if x >= 1.0:
        return C_max
    return C_leak + (C_max - C_leak) * x


def sonic_conductance_from_nominal_flow(q_n: float, p1: float, p2: float, b: float, m: float = 0.5,
                                        r_lam: float = 1.0) -> float:
    """The ISO 6358 sonic conductance C [m^3/(s Pa)] of a valve whose catalogue gives its standard
    nominal flow ``q_n`` [m^3/s, ANR] at upstream pressure p1 and downstream p2 [Pa abs]:

        C = q_n / (p1 omega(p2/p1, b, m))              (Eq. (8) solved for C, T1 = T_ref)

    Catalogues (FESTO's "standard nominal flow rate" q_nN) quote the flow at p1 = 6 bar gauge,
    p2 = 5 bar gauge; b is the fully open valve's critical ratio.

    Worked number: 700 L/min at 7.013 -> 6.013 bar abs with b = 0.3: sigma = 0.8574, omega =
    sqrt(1 - ((0.8574 - 0.3)/0.7)^2) = 0.6049 and C = 11.67 L/s / (7.013 bar 0.6049) = 2.75 L/(s bar).
    """
    return q_n / (p1 * iso6358_flow_function(p2 / p1, b, m, r_lam))


@jit
def spool_lag(x0: float, xc: float, dt: float, tau: float):
    """First-order spool response to a command held over one period: (position at the period's
    end, mean position over the period) [-].

        tau dx/dt = xc - x       =>  x(t) = xc + (x0 - xc) exp(-t / tau)
        x(dt)  = xc + (x0 - xc) a,                    a = exp(-dt / tau)
        mean x = xc + (x0 - xc) (tau / dt) (1 - a)

    x0: the position at the period's start, xc: the commanded position, dt [s] the period, tau [s]
    the time constant (1 / (2 pi f_c) for a -3 dB bandwidth f_c); tau = 0: the spool follows at
    once. Exact for a command constant over the period (the driver's assumption).

    Worked numbers: x0 = 0, xc = 1, dt = tau: end 1 - 1/e = 0.632, mean 1/e = 0.368.
    """
    if tau <= 0.0:
        return xc, xc
    a = math.exp(-dt / tau)
    return xc + (x0 - xc) * a, xc + (x0 - xc) * (tau / dt) * (1.0 - a)
