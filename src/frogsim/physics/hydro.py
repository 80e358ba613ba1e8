"""Quasi-steady hydrodynamics of the frog's body, legs and palms: drag, added mass, buoyancy.

Drag (Morison's quadratic term with the cross-flow principle; Hoerner 1965, Fluid-Dynamic Drag,
ch. 3): every part is cut into strips along its axis e1. A strip at distance s sees the water
velocity -v(s) of its own motion v(s) = v_ref + omega x (r(s) - r_ref), split into its components
v_j = v . e_j in the part's frame. Each component is resisted on its own,

    dF_j = -1/2 rho (C_j D_j(s) + C_f P_j(s)) |v_j| v_j ds                       j = 1, 2, 3   (D)

with D_j the width the strip shows to a flow along e_j (pressure drag, coefficient C_j) and P_j
the wetted width a flow along e_j slides over (skin friction, C_f). The strips are the nodes of a
Gauss-Legendre rule on the part's length, so a plate whose strip speeds grow linearly (rotation
about an edge) is integrated exactly.

Added mass (potential flow; Lamb 1932, Hydrodynamics, ch. VI): the water a part accelerates adds to
its inertia. Per part, in its own frame, a diagonal added mass m_A = (m_1, m_2, m_3) and added
inertia I_A. Values: circular cylinder m' = rho pi R^2 per length (normal to the axis); flat
rectangular plate m = C_A rho pi a^2 b / 4 with C_A from the aspect ratio (DNV-RP-H103 (2011),
Table A-2); ellipsoid from Lamb's integrals (:func:`ellipsoid_added_mass`). How the engine puts it
in MuJoCo's mass matrix is in :mod:`frogsim.engine.coupled`.

Buoyancy (Archimedes): F = rho g V upward at the centre of the displaced volume.
"""
from __future__ import annotations

import math

import numpy as np

from frogsim._jit import jit

#: DNV-RP-H103 (2011) Appendix A, Table A-2, rectangular plate moving normal to itself:
#: m_A = C_A rho pi a^2 b / 4 with a the short side, b the long side; (b/a, C_A)
PLATE_ASPECT = (1.0, 1.25, 1.5, 1.59, 2.0, 2.5, 3.0, 4.0, 5.0, 6.25, 8.0, 10.0)
PLATE_CA = (0.579, 0.642, 0.690, 0.704, 0.757, 0.801, 0.830, 0.871, 0.897, 0.917, 0.934, 0.947)


@jit
def quadratic_drag(rho: float, coefficient: float, area: float, v: float) -> float:
    """Quadratic drag F = -1/2 rho C A |v| v on a part moving at v through still water  [N].

    rho [kg/m^3], coefficient C [-] on the reference area A [m^2], v [m/s]. Worked number: the
    open palm (0.0335 m^2, C = 1.17) at 1 m/s in fresh water: -19.6 N.
    """
    return -0.5 * rho * coefficient * area * abs(v) * v


@jit
def strip_drag(k1: float, k2: float, k3: float, v1: float, v2: float, v3: float):
    """Eq. (D) for one strip: forces (F1, F2, F3) [N] in the part's frame.

    k_j = 1/2 rho (C_j D_j + C_f P_j) ds  [kg/m] is the strip's drag constant along e_j
    (:func:`strip_constants`); v_j [m/s] the strip's velocity components.
    """
    return -k1 * abs(v1) * v1, -k2 * abs(v2) * v2, -k3 * abs(v3) * v3


def gauss_strips(n: int, start: float, end: float):
    """Gauss-Legendre nodes s_k [m] and weights ds_k [m] on [start, end] (exact to degree 2n-1)."""
    x, w = np.polynomial.legendre.leggauss(n)
    half = 0.5 * (end - start)
    return start + half * (x + 1.0), half * w


def strip_constants(rho: float, widths, wetted, coefficients, skin_friction: float, ds):
    """k_j per strip for Eq. (D): 1/2 rho (C_j D_j + C_f P_j) ds, shape (n, 3)  [kg/m].

    widths, wetted: (n, 3) arrays of D_j and P_j [m]; coefficients: (C_1, C_2, C_3) [-];
    skin_friction C_f [-]; ds: (n,) strip lengths [m].
    """
    D = np.asarray(widths, float)
    P = np.asarray(wetted, float)
    C = np.asarray(coefficients, float)
    return 0.5 * rho * (C[None, :] * D + skin_friction * P) * np.asarray(ds, float)[:, None]


def plate_added_mass_coefficient(aspect: float) -> float:
    """C_A of a rectangular plate moving normal to itself (DNV-RP-H103 Table A-2)  [-].

    aspect = long side / short side >= 1; linear between the table's rows, and towards the 2-D
    strip value 1 (a plate of infinite span) as 1 - (1 - 0.947) * 10 / aspect beyond 10.
    """
    if aspect < 1.0:
        aspect = 1.0 / aspect
    if aspect > PLATE_ASPECT[-1]:
        return 1.0 - (1.0 - PLATE_CA[-1]) * PLATE_ASPECT[-1] / aspect
    return float(np.interp(aspect, PLATE_ASPECT, PLATE_CA))


def ellipsoid_added_mass(a: float, b: float, c: float, rho: float):
    """Added masses (m_1, m_2, m_3) [kg] and inertias (I_1, I_2, I_3) [kg m^2] of an ellipsoid.

    Semi-axes a, b, c [m] along e1, e2, e3. Lamb (1932) art. 114-115 with
    alpha_i = a b c int_0^inf dl / ((a_i^2 + l) sqrt((a^2 + l)(b^2 + l)(c^2 + l))):

        m_i = rho V alpha_i / (2 - alpha_i),      V = 4/3 pi a b c
        I_1 = rho V / 5 (b^2 - c^2)^2 (alpha_3 - alpha_2) / (2 (b^2 - c^2) + (b^2 + c^2)(alpha_2 - alpha_3))

    and cyclically. A sphere gives alpha = 2/3 and m = rho V / 2.
    """
    from scipy.integrate import quad
    axes = (a, b, c)

    def alpha(i):
        ai = axes[i]
        f = lambda lam: 1.0 / ((ai * ai + lam) * math.sqrt((a * a + lam) * (b * b + lam) * (c * c + lam)))
        return a * b * c * quad(f, 0.0, np.inf, limit=200)[0]

    al = [alpha(i) for i in range(3)]
    V = 4.0 / 3.0 * math.pi * a * b * c
    m = tuple(rho * V * x / (2.0 - x) for x in al)
    inertia = []
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        bj, bk = axes[j] ** 2, axes[k] ** 2
        den = 2.0 * (bj - bk) + (bj + bk) * (al[j] - al[k])
        inertia.append(0.0 if abs(bj - bk) < 1e-15 else
                       rho * V / 5.0 * (bj - bk) ** 2 * (al[k] - al[j]) / den)
    return m, tuple(inertia)


@jit
def buoyancy(rho: float, g: float, volume: float) -> float:
    """Archimedes: upward force rho g V on a displaced volume V [m^3]  [N]."""
    return rho * g * volume
