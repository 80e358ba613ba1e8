"""Air as an ideal gas and the ISO reference atmosphere used for "standard" volumes.

Standard (ANR) volumes follow ISO 8778 / ISO 6358: p_ref = 100 kPa, T_ref = 293.15 K. A flow in
"L/min" at standard state is a mass flow divided by the reference density rho_ref = p_ref/(R T_ref).
"""
from __future__ import annotations

import math

from frogsim._jit import jit


@jit
def density(p: float, T: float, R: float) -> float:
    """Ideal-gas density rho = p / (R T)  [kg/m^3]; p [Pa abs], T [K], R [J/(kg K)]."""
    return p / (R * T)


@jit
def speed_of_sound(T: float, R: float, k: float) -> float:
    """Speed of sound of an ideal gas a = sqrt(k R T)  [m/s]; 343.2 m/s for air at 293.15 K."""
    return math.sqrt(k * R * T)


@jit
def critical_pressure_ratio(k: float) -> float:
    """Isentropic critical pressure ratio of a nozzle, (2/(k+1))^(k/(k-1)) [-]; 0.528 for k = 1.4."""
    return (2.0 / (k + 1.0)) ** (k / (k - 1.0))


@jit
def choked_mass_flux_factor(R: float, k: float) -> float:
    """Factor psi in the ideal choked mass flow  m_dot = A p1 psi / sqrt(T1)  [s K^0.5 / m].

    psi = sqrt(k/R) (2/(k+1))^((k+1)/(2(k-1))); 0.0404 for air (k = 1.4, R = 287).
    Reference: any gas-dynamics text, e.g. Anderson, Modern Compressible Flow, Eq. (5.21).
    """
    return math.sqrt(k / R) * (2.0 / (k + 1.0)) ** ((k + 1.0) / (2.0 * (k - 1.0)))
