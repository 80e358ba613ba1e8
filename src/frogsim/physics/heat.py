"""Heat through the walls of the air volumes (muscles, source and exhaust chambers).

The paper takes every volume as adiabatic (Sec. 3.1: dQ_s = 0, "rapid pressurizing and
depressurizing processes ... can be regarded as adiabatic"). Over a 1 s hold that no longer holds:
a charged muscle's air, heated by compression, cools back towards the wall through a thin rubber
tube. Newton's law of cooling gives the heat flow into the air,

    Q = h A (T_wall - T)                                                          [W]

with h the convective heat transfer coefficient between the air and the wall [W/(m^2 K)] and A
the wetted wall area [m^2]. In the first law of an open volume (:mod:`frogsim.physics.gas`,
Eq. (*)) it adds (k - 1) Q to V dp/dt:

    V dp/dt = k R (sum_in m_dot T_in - m_dot_out T) - k p dV/dt + (k - 1) Q          (**)

since dU = c_v d(m T) = V dp / (k - 1) for an ideal gas with constant c_v = R / (k - 1).
Carneiro and Gomes de Almeida (2006, Proc. IMechE Part I 220:301) show that this wall term,
with h of the order of 10-30 W/(m^2 K) for small pneumatic chambers, brings a chamber's
predicted pressure to within a tenth of the polytropic models' error; McKibben muscle models
with the same term have been checked against measured pressure and air temperature (Doumit and
Pardoel 2017, Mech. Syst. Signal Process. 91:93).

For a closed rigid volume (no flow, dV = 0) (**) is linear in T: the air relaxes to T_wall as
exp(-t / tau) with tau = m c_v / (h A) (:func:`cooling_time_constant`), and p = m R T / V
follows it.
"""
from __future__ import annotations

import math

from frogsim._jit import jit


@jit
def wall_heat_flow(h: float, area: float, T_wall: float, T: float) -> float:
    """Q = h A (T_wall - T): heat flowing from the wall into the air [W].

    Args: h [W/(m^2 K)]; area [m^2]; T_wall, T [K]. Positive when the wall is warmer than the air.
    """
    return h * area * (T_wall - T)


@jit
def heat_pressure_rate(Q: float, V: float, k: float) -> float:
    """The wall's share of dp/dt in Eq. (**): (k - 1) Q / V  [Pa/s].

    Args: Q heat flow into the air [W]; V volume [m^3]; k heat capacity ratio [-].
    """
    return (k - 1.0) * Q / V


@jit
def muscle_wall_area(L: float, b0: float, n: float) -> float:
    """Inner wall area of the braided cylinder, A = pi D L with D = sqrt(b0^2 - L^2)/(n pi)  [m^2].

    The same cylinder as Eq. (5)'s volume (:func:`frogsim.physics.muscle.muscle_volume`): the area
    follows the muscle as it contracts (it widens while it shortens). The end caps are left out,
    as Eq. (5) leaves out the non-cylindrical ends.
    """
    return L * math.sqrt(max(b0 * b0 - L * L, 0.0)) / n


def cylinder_wall_area(volume: float, length_over_diameter: float) -> float:
    """Inner wall area of a closed cylinder (mantle and both ends) of the given volume [m^3] and
    length-to-diameter ratio [-]  [m^2]: D = (4 V / (pi l_d))^(1/3), A = pi D^2 (l_d + 1/2)."""
    D = (4.0 * volume / (math.pi * length_over_diameter)) ** (1.0 / 3.0)
    return math.pi * D * D * (length_over_diameter + 0.5)


def cooling_time_constant(mass: float, R: float, k: float, h: float, area: float) -> float:
    """tau = m c_v / (h A) with c_v = R / (k - 1): the time constant of a closed rigid volume's air
    relaxing to its wall temperature  [s]."""
    return mass * R / (k - 1.0) / (h * area)
