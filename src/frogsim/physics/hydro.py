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
Table A-2); ellipsoid from Lamb's integrals (:func:`ellipsoid_added_mass`). A palm's added mass
follows its fan angle (:func:`fan_added_mass`). In motion the added mass gives, besides -m_A a,
the velocity terms of Kirchhoff's equations (:func:`kirchhoff_velocity_force`,
:func:`munk_moment`) and, while it changes, -dm_A/dt v (:func:`added_mass_rate_force`). How the
engine puts it in MuJoCo's mass matrix is in :mod:`frogsim.engine.coupled_kernel`.

Vectors are passed as (x, y, z) tuples or scalar components; "part frame" components are along the
part's axes e1, e2, e3 (its MuJoCo body frame), "world" ones along the world axes.

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
def cross(ax, ay, az, bx, by, bz):
    """Components of the cross product a x b."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


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


@jit
def strip_drag_wrench(s, k, scale, origin, e1, e2, e3, omega, v_ref, r_ref, r_moment):
    """Eq. (D) summed over a part's strips: force [N] and its moment [N m] about r_moment, world.

    The part is rigid: a point r moves at v(r) = v_ref + omega x (r - r_ref) (v_ref [m/s] the
    velocity of the point r_ref [m], omega [rad/s]). Strip i sits at r_i = origin + s[i] e1 (s [m]
    along the part's axis e1 from origin; e1, e2, e3 the part's unit axes in world components) and
    has the drag constants scale k[i, j] [kg/m] (``scale``: a palm's fan angle, as its strips are
    stored per radian). Each strip's force :func:`strip_drag` acts at r_i.

    Returns (Fx, Fy, Fz, Mx, My, Mz), world components.
    """
    ox, oy, oz = origin
    e1x, e1y, e1z = e1
    e2x, e2y, e2z = e2
    e3x, e3y, e3z = e3
    wx, wy, wz = omega
    lx, ly, lz = v_ref
    rx, ry, rz = r_ref
    gx, gy, gz = r_moment
    Fx = 0.0
    Fy = 0.0
    Fz = 0.0
    Tx = 0.0
    Ty = 0.0
    Tz = 0.0
    for i in range(s.size):
        si = s[i]
        px, py, pz = ox + e1x * si, oy + e1y * si, oz + e1z * si
        cx, cy, cz = cross(wx, wy, wz, px - rx, py - ry, pz - rz)
        vx, vy, vz = lx + cx, ly + cy, lz + cz
        f1, f2, f3 = strip_drag(k[i, 0] * scale, k[i, 1] * scale, k[i, 2] * scale,
                                e1x * vx + e1y * vy + e1z * vz, e2x * vx + e2y * vy + e2z * vz,
                                e3x * vx + e3y * vy + e3z * vz)
        fx = f1 * e1x + f2 * e2x + f3 * e3x
        fy = f1 * e1y + f2 * e2y + f3 * e3y
        fz = f1 * e1z + f2 * e2z + f3 * e3z
        Fx += fx
        Fy += fy
        Fz += fz
        tx, ty, tz = cross(px - gx, py - gy, pz - gz, fx, fy, fz)
        Tx += tx
        Ty += ty
        Tz += tz
    return Fx, Fy, Fz, Tx, Ty, Tz


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
def fan_added_mass(m1, m2, m3, i1, i2, i3, phi):
    """Added masses [kg] and inertias [kg m^2] of a palm opened to the fan angle phi [rad].

    The palm is a fan of spokes: at distance s from the ankle its strip is a plate of height
    h = s phi. By strip theory (Newman 1977, Marine Hydrodynamics, ch. 4; the 2-D flat plate's
    added mass pi rho h^2 / 4 per length, DNV-RP-H103 (2011) App. A) every added mass and the
    inertias about the axes across the spokes grow as h^2, so as phi^2; the inertia about the
    spokes' axis e1 (each strip rolling about its centre line: pi rho h^4 / 128 per length) as
    phi^4. (m1, m2, m3, i1, i2, i3) are the values per rad^2 (i1 per rad^4) that
    :mod:`frogsim.robot.water` stores; a part of fixed shape passes its own values and phi = 1.

    Returns (m_1, m_2, m_3, I_1, I_2, I_3) along / about the part's axes e1, e2, e3.
    """
    s2 = phi * phi
    s4 = phi * phi * phi * phi
    return m1 * s2, m2 * s2, m3 * s2, i1 * s4, i2 * s2, i3 * s2


@jit
def isotropic_added_mass(m1, m2, m3, heave):
    """The added mass m_iso [kg] the coupled engine puts into a part's body as an isotropic mass:
    the largest of m_1, m_2 and (if the part can move along its e3, ``heave``) m_3.

    The rest, (m_iso - m_j) a_j along each axis, goes back as an explicit force, an iteration that
    contracts because m_iso >= m_j (:mod:`frogsim.engine.coupled_kernel`).
    """
    miso = max(m1, m2)
    if heave:
        miso = max(miso, m3)
    return miso


@jit
def kirchhoff_velocity_force(m1, m2, m3, w1, w2, w3, v1, v2, v3):
    """Velocity terms of the water's force on a part with diagonal added mass M_A = diag(m_j):

        F_v = M_A (omega x v) - omega x (M_A v)                                               [N]

    Kirchhoff's equations (Lamb 1932, Hydrodynamics, ch. VI; Newman 1977, ch. 4): in the part's
    frame the water's force is -d(M_A v)/dt - omega x (M_A v), and d(v)/dt seen from the
    rotating frame is a - omega x v, with a the acceleration (world, taken to part components),
    so F = -M_A a + F_v. Potential flow, the water at rest far away, a body that does not
    deform. m_j [kg]; omega (w_j) [rad/s] and v (v_j) [m/s] of the added mass's centre, both in
    part components. Zero without rotation, and zero when all m_j are equal.

    Returns (F_1, F_2, F_3), part components.
    """
    ox1, ox2, ox3 = cross(w1, w2, w3, v1, v2, v3)                 # omega x v
    p1, p2, p3 = m1 * v1, m2 * v2, m3 * v3                         # M_A v
    oy1, oy2, oy3 = cross(w1, w2, w3, p1, p2, p3)                 # omega x (M_A v)
    return m1 * ox1 - oy1, m2 * ox2 - oy2, m3 * ox3 - oy3


@jit
def munk_moment(m1, m2, m3, v1, v2, v3):
    """Munk moment of a part translating at v through still water:

        M = (M_A v) x v = -v x (M_A v)                                                       [N m]

    Kirchhoff's equations (Lamb 1932, ch. VI; Newman 1977, ch. 4; Munk 1924, NACA Report 184),
    the torque term from the fluid impulse. It turns an elongated body broadside to its motion
    (unstable) and vanishes when v is along a principal axis or the added masses are equal. m_j
    [kg], v [m/s] in part components.

    Returns (M_1, M_2, M_3), part components.
    """
    return cross(m1 * v1, m2 * v2, m3 * v3, v1, v2, v3)


@jit
def added_mass_rate_force(m_now, m_next, dt, v):
    """-dm/dt v: the reaction of water taken along by a part whose added mass grows [N].

    d(m_A v)/dt = m_A dv/dt + (dm_A/dt) v: when a palm opens, the water it sets moving must be
    brought to its speed. Here the rate is the change over the step, (m_next - m_now) / dt
    [kg/s], v [m/s] the velocity component along that added mass's axis. The same with an added
    inertia [kg m^2] and an angular velocity [rad/s] gives the moment [N m].
    """
    return -(m_next - m_now) / dt * v


@jit
def buoyancy(rho: float, g: float, volume: float) -> float:
    """Archimedes: upward force rho g V on a displaced volume V [m^3]  [N]."""
    return rho * g * volume
