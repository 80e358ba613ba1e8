"""Geometry and mass budget of the robot: hull, legs, cranks, derived from the parameter set.

Frames. The body frame has x forward (the direction the frog faces), y to the left, z up. The legs
move in the x-y plane (paper Sec. 2.1: "all the limbs moved in planar space"): every joint turns
about the vertical. Each leg segment's frame has its origin at the joint that moves it and its x
axis along the segment. The joint angle theta is 0 at the flexed stop and grows with extension;
the right leg is the mirror image of the left (its joint axes point down, so that a positive angle
is an extension on both sides).

Cranks (paper Sec. 2.2.2, Figs. 3 and 6). Each joint has a driving (extensor) and a recovery
(flexor) muscle, both between an anchor on the parent segment and a pin on the crank of the child
segment. The anchor sits at distance d from the joint axis along the parent's anchor direction
alpha (hip: forward along the body; knee, ankle: back along the parent segment); the pins at
radius r. The driving muscle has its rest length at theta = 0 with its crank perpendicular to the
line joint-anchor, and shortens as the joint extends; the recovery muscle is its mirror image about
the middle of the range: rest length at theta = range, shortest at theta = 0. Both lengths are
:func:`frogsim.physics.muscle.crank_muscle_length` (law of cosines); in MuJoCo the same distance is
the length of a spatial tendon between the two sites, and the muscle length is that distance less
the fixed length of the fittings c = sqrt(d^2 + r^2) - L0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from frogsim.errors import ScenarioError
from frogsim.physics.muscle import crank_muscle_length
from frogsim.robot.params import JOINTS, RobotParams

#: anchor direction of each joint's muscles in its parent's frame [rad]
ANCHOR_DIRECTION = {"hip": 0.0, "knee": math.pi, "ankle": math.pi}


@dataclass(frozen=True)
class Crank:
    """One joint's crank and muscle mounting (left leg; 2-D, in the frames described above)."""
    joint: str
    rest_length: float          # L0 [m]
    crank_radius: float         # r [m]
    anchor_distance: float      # d [m]
    range: float                # [rad]
    max_contraction: float      # [-]
    anchor: tuple               # anchor site in the parent frame (x, y) [m]
    drive_pin: tuple            # driving pin in the child frame at theta = 0 [m]
    recovery_pin: tuple         # recovery pin in the child frame [m]

    @property
    def fittings(self) -> float:
        """c = sqrt(d^2 + r^2) - L0: site-to-site distance minus muscle length [m]."""
        return math.hypot(self.anchor_distance, self.crank_radius) - self.rest_length

    def drive_length(self, theta: float) -> float:
        """Driving muscle length at joint angle theta [m] (rest length at theta = 0)."""
        return crank_muscle_length(theta, self.anchor_distance, self.crank_radius, 0.0,
                                   self.rest_length, 1.0)

    def recovery_length(self, theta: float) -> float:
        """Recovery muscle length at joint angle theta [m] (rest length at theta = range)."""
        return crank_muscle_length(theta, self.anchor_distance, self.crank_radius, self.range,
                                   self.rest_length, -1.0)


def crank(robot: RobotParams, muscle_types: dict, joint: str, parent_joint_pos) -> Crank:
    """The crank of ``joint`` with the joint at ``parent_joint_pos`` (x, y) in its parent frame.

    Pins (child frame, theta = 0): the driving pin at angle alpha - 90 deg seen from the parent,
    the recovery pin at alpha + 90 deg - range, both turned into the child frame by the flexed
    angle (extended_angle - range). Refuses a range of 90 deg or more (the crank would pass its
    dead centre) and one that contracts the driving muscle beyond its max_contraction (the
    contraction grows with the angle below 90 deg, so the end of the range is the worst).
    """
    j = robot.joints[joint]
    mt = muscle_types[j.muscle_type]
    alpha = ANCHOR_DIRECTION[joint]
    psi = j.extended_angle - j.range
    r, d = mt.crank_radius, mt.anchor_distance
    x0, y0 = parent_joint_pos
    anchor = (x0 + d * math.cos(alpha), y0 + d * math.sin(alpha))
    a_drive = alpha - 0.5 * math.pi - psi
    a_rec = alpha + 0.5 * math.pi - j.range - psi
    c = Crank(joint, mt.nominal_length, r, d, j.range, mt.max_contraction, anchor,
              (r * math.cos(a_drive), r * math.sin(a_drive)),
              (r * math.cos(a_rec), r * math.sin(a_rec)))
    if j.range >= 0.5 * math.pi:
        raise ScenarioError(f"joints.{joint}.range", f"{math.degrees(j.range):.4g} deg",
                            "must be below 90 deg: the crank would pass its dead centre, where the "
                            "muscle's moment arm vanishes and reverses")
    worst = 1.0 - c.drive_length(j.range) / mt.nominal_length
    if worst > mt.max_contraction:
        raise ScenarioError(f"joints.{joint}.range", f"{math.degrees(j.range):.4g} deg",
                            f"contracts the driving muscle by {worst:.1%} at full extension, beyond "
                            f"its max_contraction ({mt.max_contraction:.0%})")
    return c


@dataclass(frozen=True)
class Layout:
    """Derived dimensions and masses of the whole robot (SI)."""
    body_semi_axes: tuple       # (a, b, c) [m] of the ellipsoidal hull
    body_volume: float          # [m^3]
    segment_volume: dict        # joint -> volume of the segment it moves [m^3]
    trunk_mass: float           # hull and contents without ballast [kg]
    ballast: float              # [kg]
    body_com: tuple             # centre of mass of hull + ballast in the body frame [m]
    body_inertia: tuple         # principal moments about body_com (x, y, z) [kg m^2]
    segment_inertia: dict       # joint -> (Ixx, Iyy, Izz) about the segment's centre of mass
    cranks: dict                # joint -> Crank
    joint_pos: dict             # joint -> (x, y) of the joint in its parent frame (left leg)
    segment_mass: dict          # joint -> mass of the segment it moves [kg]

    @property
    def total_mass(self) -> float:
        """Robot with ballast [kg]."""
        return self.trunk_mass + self.ballast + 2.0 * sum(self.segment_mass.values())

    @property
    def total_volume(self) -> float:
        """Displaced volume of hull and both legs [m^3] (Table 1's displacement by construction)."""
        return self.body_volume + 2.0 * sum(self.segment_volume.values())


def palm_fan_angle(area: float, length: float) -> float:
    """Opening angle of the palm's fan of spokes with the given membrane area [rad].

    The palm is a circular sector of radius l (the spokes, Table 1 palm length) and angle phi,
    area A = phi l^2 / 2 (paper Fig. 5: spokes fanned out from the joint connector).
    """
    return 2.0 * area / (length * length)


def layout(robot: RobotParams, muscle_types: dict) -> Layout:
    """Dimensions, masses and inertias of every part, and the three cranks of the left leg.

    The hull is an ellipsoid of Table 1's length and width whose height makes the whole robot
    displace Table 1's 19 L: hull volume = displacement - 2 (thigh + crus cylinders + palm plate).
    The hull's mass is the total mass less the legs'; the ballast sits at ballast_depth below the
    hull's centre. Inertias: uniform solid ellipsoid for the hull, solid cylinders for thigh and
    crus, a thin plate (length x mean height x thickness) for the palm.
    """
    legs, body = robot.legs, robot.body
    R = legs.segment_radius
    seg_vol = {"hip": math.pi * R * R * legs.thigh_length,
               "knee": math.pi * R * R * legs.crus_length,
               "ankle": robot.palms.open_area * legs.palm_thickness}
    body_vol = body.displacement - 2.0 * sum(seg_vol.values())
    if body_vol <= 0.0:
        raise ScenarioError("body.displacement", f"{body.displacement * 1e3:g} L",
                            "is less than the legs' own volume")
    a, b = 0.5 * body.length, 0.5 * body.width
    c = 3.0 * body_vol / (4.0 * math.pi * a * b)
    seg_mass = {j: legs.segment_mass(j) for j in JOINTS}
    trunk = body.total_mass - 2.0 * sum(seg_mass.values())
    if trunk <= 0.0:
        raise ScenarioError("body.total_mass", f"{body.total_mass:g} kg",
                            "must exceed the mass of the two legs")
    ballast = body.ballast_mass(robot.water.density)
    m = trunk + ballast
    zc = -ballast * body.ballast_depth / m
    dz_b = -body.ballast_depth - zc
    Ixx = trunk * (b * b + c * c) / 5.0 + trunk * zc * zc + ballast * dz_b * dz_b
    Iyy = trunk * (a * a + c * c) / 5.0 + trunk * zc * zc + ballast * dz_b * dz_b
    Izz = trunk * (a * a + b * b) / 5.0
    seg_inertia = {}
    for j in ("hip", "knee"):
        mj, lj = seg_mass[j], legs.segment_length(j)
        seg_inertia[j] = (0.5 * mj * R * R, mj * (3 * R * R + lj * lj) / 12.0,
                          mj * (3 * R * R + lj * lj) / 12.0)
    mp, lp = seg_mass["ankle"], legs.palm_length
    h, t = robot.palms.open_area / lp, legs.palm_thickness
    seg_inertia["ankle"] = (mp * (h * h + t * t) / 12.0, mp * (lp * lp + h * h) / 12.0,
                            mp * (lp * lp + t * t) / 12.0)
    joint_pos = {"hip": (legs.hip_x, legs.hip_y), "knee": (legs.thigh_length, 0.0),
                 "ankle": (legs.crus_length, 0.0)}
    cranks = {j: crank(robot, muscle_types, j, joint_pos[j]) for j in JOINTS}
    return Layout((a, b, c), body_vol, seg_vol, trunk, ballast, (0.0, 0.0, zc), (Ixx, Iyy, Izz),
                  seg_inertia, cranks, joint_pos, seg_mass)


def leg_points(robot: RobotParams, angles) -> np.ndarray:
    """Hip, knee, ankle and palm tip of the left leg in the body frame for joint angles
    (hip, knee, ankle) [rad]: a (4, 2) array [m]. Planar forward kinematics, for plots and tests."""
    legs = robot.legs
    pts = [np.array([legs.hip_x, legs.hip_y])]
    heading = 0.0
    for j, th in zip(JOINTS, angles):
        jp = robot.joints[j]
        heading += jp.extended_angle - jp.range + th
        L = legs.segment_length(j)
        pts.append(pts[-1] + L * np.array([math.cos(heading), math.sin(heading)]))
    return np.array(pts)
