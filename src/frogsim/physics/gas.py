"""Thermodynamics of the air volumes: source chamber, exhaust chamber, muscles (paper Sec. 3.1-3.2).

All volumes are adiabatic open systems (the paper's assumption dQ = 0: filling and venting are faster
than heat exchange through the walls). The first law for a volume V with pressure p and temperature
T = p V/(m R), receiving mass at temperature T_in and losing mass at its own temperature, gives

    V dp/dt = k R (sum_in m_dot T_in - m_dot_out T) - k p dV/dt                      (*)

The paper's Eqs. (2), (4), (6) and (7) are special cases of (*):

* Eq. (2), source chamber, rigid, outflow only:           dp_s = -k R T_s dM / V_s
* Eq. (4), exhaust chamber, rigid, inflow at muscle T:    V_e dp_e = k R T dm
* Eq. (6), muscle charging from the source at T_s:        k R T_s dM = k P dV + V dP
* Eq. (7), muscle discharging at its own temperature T:   -k R T dm = k P dV + V dP

The engine uses (*) through :func:`pressure_rate`; the special cases are kept as functions so each
equation of the paper can be read and tested on its own.
"""
from __future__ import annotations

from frogsim._jit import jit


@jit
def pressure_rate(p: float, V: float, dVdt: float, enthalpy_in: float, mdot_out: float,
                  T: float, R: float, k: float) -> float:
    """General adiabatic open-volume pressure rate, Eq. (*) above  [Pa/s].

    Args:
        p: pressure [Pa abs]; V: volume [m^3]; dVdt: volume rate [m^3/s].
        enthalpy_in: sum over inflows of m_dot_in * T_in [kg K/s].
        mdot_out: total outflow [kg/s], leaving at the volume's own temperature T [K].
        R: gas constant [J/(kg K)]; k: heat capacity ratio [-].
    """
    return (k * R * (enthalpy_in - mdot_out * T) - k * p * dVdt) / V


@jit
def source_pressure_rate(mdot_out: float, T_s: float, V_s: float, R: float, k: float) -> float:
    """Eq. (2): dp_s/dt = -k R T_s (dM/dt) / V_s for the rigid source chamber  [Pa/s].

    Assumes no heat exchange and no supply (pump off); mdot_out [kg/s] > 0 leaves the chamber.
    """
    return -k * R * T_s * mdot_out / V_s


@jit
def adiabatic_temperature(p: float, p0: float, T0: float, k: float) -> float:
    """Eq. (3): T/T0 = (p/p0)^((k-1)/k) for a chamber that only discharges adiabatically  [K]."""
    return T0 * (p / p0) ** ((k - 1.0) / k)


@jit
def exhaust_pressure_rate(mdot_in: float, T_in: float, V_e: float, R: float, k: float) -> float:
    """Eq. (4): V_e dp_e = k R T dm for the rigid exhaust chamber receiving air at T_in  [Pa/s]."""
    return k * R * T_in * mdot_in / V_e


@jit
def muscle_charge_pressure_rate(p: float, V: float, dVdt: float, mdot_in: float, T_s: float,
                                R: float, k: float) -> float:
    """Eq. (6): k R T_s dM = k P dV + V dP for a moving-volume muscle charged at T_s  [Pa/s]."""
    return (k * R * T_s * mdot_in - k * p * dVdt) / V


@jit
def muscle_discharge_pressure_rate(p: float, V: float, dVdt: float, mdot_out: float, T: float,
                                   R: float, k: float) -> float:
    """Eq. (7): -k R T dm = k P dV + V dP for a muscle venting at its own temperature T  [Pa/s]."""
    return (-k * R * T * mdot_out - k * p * dVdt) / V
