"""The parts the water acts on: hull, thighs, cruses and palms as strips, added masses, volumes.

:func:`hydro_tables` turns a robot scenario into the flat tables the coupled engine loops over
(:mod:`frogsim.engine.coupled`; columns E_* and P_* below). Per part, in the frame of its MuJoCo body
(x along the part):

hull    ellipsoid with semi-axes (a, b, c) (:class:`frogsim.robot.geometry.Layout`): strips on
        [-a, a]; axial drag C_x pi b c spread over the strips; across, local widths 2 c(s) (flow
        along y) and 2 b(s) (flow along z) with the lateral and vertical coefficients; added mass
        and inertia of the ellipsoid (Lamb).
thigh,  cylinder of radius R on [0, l]: cross-flow drag C_cyl 2R per length, skin friction on the
crus    perimeter 2 pi R along the axis; added mass rho pi R^2 per length across the axis
        (potential flow around a circle), none along it.
palm    fan of spokes of length l opened to the angle phi: strip height s phi at distance s from
        the ankle; normal drag C_plate s phi, skin friction on both faces for flow in its plane;
        added mass C_A rho pi (s phi)^2 / 4 per length normal to the plate, C_A of a rectangular
        plate of the open palm's aspect ratio l^2 / S (DNV-RP-H103). Everything is stored per
        radian of fan angle (strips per rad, masses per rad^2) and scaled by the engine as the
        steering motor opens and folds the palm.
"""
from __future__ import annotations

import math

import numpy as np

from frogsim.physics.hydro import (ellipsoid_added_mass, gauss_strips, plate_added_mass_coefficient,
                                   strip_constants)
from frogsim.robot.geometry import palm_fan_angle
from frogsim.robot.mjcf import body_name
from frogsim.robot.params import JOINTS, SIDES


# --- element table el[e, :] (one row per part in the water) -------------------------------------
E_BODY = 0       # MuJoCo body id
E_FAN = 1        # palm index (>= 0) for a palm whose size follows its fan angle, else -1
E_LIMB = 2       # 1 for the legs' parts (their force is the thrust), 0 for the hull
E_M0 = 3         # the body's own mass [kg]
E_C0 = 4         # its centre of mass, local x, y, z [m] (3)
E_I0 = 7         # its inertia about that centre, diagonal (3) [kg m^2]
E_MA = 10        # added masses m_1, m_2, m_3 [kg] (per rad^2 of fan angle for a palm) (3)
E_IA = 13        # added inertias I_1, I_2, I_3 [kg m^2] (palm: I_1 per rad^4, I_2, I_3 per rad^2) (3)
E_XA = 16        # centre of the added mass, local x, y, z [m] (3)
E_VOL = 19       # displaced volume [m^3]
E_XB = 20        # centre of buoyancy, local x, y, z [m] (3)
E_HEAVE = 23     # 1 if the part can move along its local z (then m_3 counts in m_iso), else 0
E_SIZE = 24

# --- palm table pa[p, :] ---------------------------------------------------------------------------
P_EL = 0         # element row of the palm
P_PHI_FOLD = 1   # fan angle folded [rad]
P_PHI_OPEN = 2   # fan angle open [rad]
P_RATE = 3       # opening fraction per second at full motor speed [1/s]
P_SIZE = 4


def _row(body, fan, limb, m0, c0, i0, ma, ia, xa, vol, xb, heave) -> np.ndarray:
    r = np.zeros(E_SIZE)
    r[E_BODY], r[E_FAN], r[E_LIMB], r[E_M0] = body, fan, limb, m0
    r[E_C0:E_C0 + 3], r[E_I0:E_I0 + 3] = c0, i0
    r[E_MA:E_MA + 3], r[E_IA:E_IA + 3] = ma, ia
    r[E_XA:E_XA + 3], r[E_VOL], r[E_XB:E_XB + 3] = xa, vol, xb
    r[E_HEAVE] = heave
    return r


def hull_part(body: int, semi_axes, mass: float, com, inertia, rho: float, axial: float,
              lateral: float, vertical: float, strips: int, heave: float):
    """(row, strip positions, strip constants) of an ellipsoidal hull (module docstring)."""
    a, b, c = semi_axes
    s, ds = gauss_strips(strips, -a, a)
    shape = np.sqrt(np.clip(1.0 - (s / a) ** 2, 0.0, None))
    widths = np.stack([np.zeros(strips), 2.0 * c * shape, 2.0 * b * shape], axis=1)
    k = strip_constants(rho, widths, np.zeros((strips, 3)), (0.0, lateral, vertical), 0.0, ds)
    k[:, 0] = 0.5 * rho * axial * math.pi * b * c * ds / (2.0 * a)
    ma, ia = ellipsoid_added_mass(a, b, c, rho)
    row = _row(body, -1, 0, mass, com, inertia, ma, ia, (0.0, 0.0, 0.0),
               4.0 / 3.0 * math.pi * a * b * c, (0.0, 0.0, 0.0), heave)
    return row, s, k


def cylinder_part(body: int, length: float, radius: float, mass: float, inertia, rho: float,
                  crossflow: float, friction: float, strips: int, heave: float):
    """(row, strips, constants) of a leg segment: a cylinder on [0, length] along x."""
    s, ds = gauss_strips(strips, 0.0, length)
    widths = np.tile([0.0, 2.0 * radius, 2.0 * radius], (strips, 1))
    wetted = np.tile([2.0 * math.pi * radius, 0.0, 0.0], (strips, 1))
    k = strip_constants(rho, widths, wetted, (0.0, crossflow, crossflow), friction, ds)
    m_line = rho * math.pi * radius * radius
    mid = (0.5 * length, 0.0, 0.0)
    row = _row(body, -1, 1, mass, mid, inertia, (0.0, m_line * length, m_line * length),
               (0.0, m_line * length ** 3 / 12.0, m_line * length ** 3 / 12.0), mid,
               math.pi * radius * radius * length, mid, heave)
    return row, s, k


def palm_part(body: int, fan: int, length: float, open_area: float, thickness: float, mass: float,
              inertia, rho: float, normal: float, friction: float, strips: int, heave: float):
    """(row, strips, constants) of a palm fan, everything per radian of fan angle (see above)."""
    s, ds = gauss_strips(strips, 0.0, length)
    widths = np.stack([np.zeros(strips), s, np.zeros(strips)], axis=1)
    wetted = np.stack([2.0 * s, np.zeros(strips), 2.0 * s], axis=1)
    k = strip_constants(rho, widths, wetted, (0.0, normal, 0.0), friction, ds)
    ca = plate_added_mass_coefficient(length * length / open_area)
    m2 = ca * rho * math.pi * length ** 3 / 12.0             # normal, per rad^2
    i3 = ca * rho * math.pi * length ** 5 / 320.0            # about 3 l / 4, per rad^2
    i1 = rho * math.pi * length ** 5 / 640.0                 # about the spoke axis, per rad^4
    row = _row(body, fan, 1, mass, (0.5 * length, 0.0, 0.0), inertia, (0.0, m2, 0.0),
               (i1, 0.0, i3), (0.75 * length, 0.0, 0.0), open_area * thickness,
               (0.5 * length, 0.0, 0.0), heave)
    return row, s, k


def hydro_tables(rs, body_id):
    """(el, strips_s, strips_k, pa) for a robot scenario; body_id(name) gives MuJoCo body ids."""
    robot, lay, opt = rs.robot, rs.layout, rs.options
    rho = rs.medium_density
    hy = robot.hydro
    ns = hy.strips
    heave = 1.0 if (opt.base == "free" and not opt.planar) else 0.0
    parts = [hull_part(body_id("body"), lay.body_semi_axes, lay.trunk_mass + lay.ballast,
                       lay.body_com, lay.body_inertia, rho, hy.body_axial_drag,
                       hy.body_lateral_drag, hy.body_vertical_drag, ns, heave)]
    palms = []
    R = robot.legs.segment_radius
    for side in SIDES:
        for joint in JOINTS:
            L = robot.legs.segment_length(joint)
            body = body_id(body_name(joint, side))
            m0, i0 = lay.segment_mass[joint], lay.segment_inertia[joint]
            if joint != "ankle":
                parts.append(cylinder_part(body, L, R, m0, i0, rho, hy.segment_crossflow_drag,
                                           hy.skin_friction, ns, heave))
                continue
            pal = robot.palms
            parts.append(palm_part(body, len(palms), L, pal.open_area, robot.legs.palm_thickness,
                                   m0, i0, rho, hy.plate_normal_drag, hy.skin_friction, ns, heave))
            p = np.zeros(P_SIZE)
            p[P_EL] = len(parts) - 1
            p[P_PHI_FOLD] = palm_fan_angle(pal.folded_area, L)
            p[P_PHI_OPEN] = palm_fan_angle(pal.open_area, L)
            p[P_RATE] = 1.0 / pal.motor_travel_time
            palms.append(p)
    el = np.array([row for row, _, _ in parts])
    return (el, np.array([s for _, s, _ in parts]), np.array([k for _, _, k in parts]),
            np.array(palms).reshape(-1, P_SIZE))
