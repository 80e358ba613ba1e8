"""The robot as a MuJoCo model (MJCF), generated from a robot scenario.

Bodies: the hull ("body", Table 1 length and width, ellipsoidal, with its ballast) and per leg
thigh, crus and palm ("thigh_left", ...), joined by hinges "hip_left", "knee_left", "ankle_left"
about the vertical (friction and damping from ``[joints]``). The hull is free (6 DoF), held to the
horizontal plane (slide x, slide y, hinge yaw) or fixed on a base.

A joint's ``range`` is written for readers (viewer, ``jnt_range``) but is not a MuJoCo limit
(``limited="false"``): the end stops are elastomer pads, a spring and damper the coupled engine
applies on a pad as a joint torque and the joint's dof damping (:mod:`frogsim.physics.stop`). MuJoCo's limit constraint fixes the
joint's acceleration per unit of its effective inertia, so it cannot hold a pad's stiffness in
N m/rad; the old 5 ms constraint stopped a swimming leg and its water within milliseconds.

Muscles are spatial tendons between an anchor site on the parent segment and a pin site on the
child's crank (:mod:`frogsim.robot.geometry`), each driven by a ``general`` actuator whose control
is the muscle's tension [N] (gain -1: a positive control shortens the tendon). In the paper's
variant the recovery muscle is replaced by a tendon with a spring (stiffness, spring length).
MuJoCo gives each tendon's length and velocity; the pneumatic model gives pressure and force
(:mod:`frogsim.engine.coupled`). MuJoCo's own fluid model is off (density 0): the water's forces
are applied by frogsim.

All geoms are visual (no contacts). Open the file written by :func:`write_mjcf` in MuJoCo's viewer
(``python -m mujoco.viewer --mjcf=frog.xml``).
"""
from __future__ import annotations

import math
from pathlib import Path

from frogsim.robot.geometry import palm_fan_angle
from frogsim.robot.params import JOINTS, SIDES

SEGMENT = {"hip": "thigh", "knee": "crus", "ankle": "palm"}
PALM_STRIPS = 6          # boxes that draw the palm's fan (visual only)
MUSCLE_Z = {"drive": 0.012, "recover": -0.012}   # the two muscles of a joint above and below [m]


def _f(x: float) -> str:
    return f"{x:.9g}"


def _vec(*xs) -> str:
    return " ".join(_f(x) for x in xs)


def _quat_z(angle: float) -> str:
    return _vec(math.cos(0.5 * angle), 0.0, 0.0, math.sin(0.5 * angle))


def body_name(joint: str, side: str) -> str:
    """MuJoCo body moved by a joint: thigh_left, crus_left, palm_left, ..."""
    return f"{SEGMENT[joint]}_{side}"


def palm_visual_heights(fan_angle: float, length: float):
    """Half-heights of the boxes drawing a palm fan opened to fan_angle [rad] (visual only)."""
    return [0.5 * fan_angle * length * (k + 0.5) / PALM_STRIPS for k in range(PALM_STRIPS)]


def build_mjcf(rs) -> str:
    """The MJCF text of a :class:`frogsim.robot.scenario.RobotScenario`."""
    robot, lay, opt = rs.robot, rs.layout, rs.options
    a, b, c = lay.body_semi_axes
    water = opt.environment == "water"
    g = robot.water.gravity
    out = []
    w = out.append
    w(f'<mujoco model="frog-{rs.name}">')
    w('  <compiler angle="radian" autolimits="true"/>')
    w(f'  <option timestep="{_f(opt.timestep)}" integrator="implicitfast" gravity="0 0 {_f(-g)}" '
      'density="0" viscosity="0">')
    w('    <flag contact="disable" autoreset="disable"/>')
    w('  </option>')
    fog = ('<map fogstart="1.5" fogend="6"/><rgba fog="0.1 0.3 0.42 1"/>' if water else "")
    w('  <visual><global offwidth="1280" offheight="960"/><quality shadowsize="0"/>'
      f'<headlight ambient="0.4 0.4 0.4" diffuse="0.6 0.6 0.6"/>{fog}</visual>')
    w('  <asset>')
    w('    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.35 0.6 0.8" '
      'rgb2="0.02 0.12 0.25" width="256" height="256"/>' if water else
      '    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.9 0.9 0.95" '
      'rgb2="0.55 0.6 0.7" width="256" height="256"/>')
    tiles = ('rgb1="0.3 0.55 0.62" rgb2="0.22 0.45 0.52"' if water else
             'rgb1="0.75 0.75 0.72" rgb2="0.62 0.62 0.6"')
    w(f'    <texture name="grid" type="2d" builtin="checker" {tiles} width="256" height="256"/>')
    w('    <material name="floor" texture="grid" texrepeat="80 80" reflectance="0"/>')
    w('    <material name="hull" rgba="0.35 0.6 0.28 0.45"/>')
    w('    <material name="shell" rgba="0.4 0.66 0.3 0.35"/>')
    w('    <material name="membrane" rgba="0.85 0.75 0.45 0.85"/>')
    w('    <material name="metal" rgba="0.6 0.6 0.65 1"/>')
    w('  </asset>')
    w('  <worldbody>')
    w('    <light pos="0 0 4" dir="0 0 -1" directional="true" castshadow="false" diffuse="0.6 0.6 0.6"/>')
    floor_z = -0.6 if water else -0.5
    w(f'    <geom name="floor" type="plane" size="40 40 0.1" pos="0 0 {_f(floor_z)}" material="floor" '
      'contype="0" conaffinity="0"/>')
    if opt.base == "fixed":
        w(f'    <geom name="base" type="cylinder" fromto="0 0 {_f(floor_z)} 0 0 {_f(-c)}" size="0.04" '
          'material="metal" contype="0" conaffinity="0"/>')
    w('    <body name="body" pos="0 0 0">')
    if opt.base == "free":
        if opt.planar:
            w('      <joint name="root_x" type="slide" axis="1 0 0" damping="0"/>')
            w('      <joint name="root_y" type="slide" axis="0 1 0" damping="0"/>')
            w('      <joint name="root_yaw" type="hinge" axis="0 0 1" damping="0"/>')
        else:
            w('      <freejoint name="root"/>')
    w('      <camera name="track" mode="trackcom" pos="-0.6 -1.9 1.7" xyaxes="0.95 -0.3 0 0.18 0.6 0.78"/>')
    w('      <camera name="top" mode="trackcom" pos="-0.35 0 2.6" xyaxes="1 0 0 0 1 0"/>')
    m_body = lay.trunk_mass + lay.ballast
    w(f'      <inertial pos="{_vec(*lay.body_com)}" quat="1 0 0 0" mass="{_f(m_body)}" '
      f'diaginertia="{_vec(*lay.body_inertia)}"/>')
    w(f'      <geom name="hull" type="ellipsoid" size="{_vec(a, b, c)}" material="hull" '
      'contype="0" conaffinity="0" mass="0"/>')
    w(f'      <geom name="head" type="sphere" size="0.03" pos="{_vec(0.8 * a, 0, 0.6 * c)}" rgba="0.1 0.1 0.1 1" '
      'contype="0" conaffinity="0" mass="0"/>')
    for side in SIDES:
        _leg(w, rs, side)
    w('    </body>')
    w('  </worldbody>')
    w('  <tendon>')
    for name, (joint, side, group) in rs.muscles.items():
        _tendon(w, name, joint, side, group, width=0.009, rgba="0.85 0.25 0.2 1")
    if opt.recovery == "spring":
        for side in SIDES:
            for joint in JOINTS:
                jp = robot.joints[joint]
                cr = lay.cranks[joint]
                s_min = cr.recovery_length(0.0) + cr.fittings
                spring_len = s_min - (jp.spring_preload / jp.spring_stiffness
                                      if jp.spring_stiffness > 0 else 0.0)
                _tendon(w, f"{joint}_{side}_spring", joint, side, "recover", width=0.003,
                        rgba="0.8 0.8 0.85 1",
                        extra=f' stiffness="{_f(jp.spring_stiffness)}" springlength="{_f(spring_len)}"')
    w('  </tendon>')
    w('  <actuator>')
    for name in rs.muscles:
        w(f'    <general name="{name}" tendon="{name}" gainprm="-1" biastype="none"/>')
    w('  </actuator>')
    w('</mujoco>')
    return "\n".join(out) + "\n"


def _leg(w, rs, side: str) -> None:
    robot, lay = rs.robot, rs.layout
    legs = robot.legs
    sy = 1.0 if side == "left" else -1.0
    R = legs.segment_radius
    indent = "      "
    opened = []
    for joint in JOINTS:
        jp = robot.joints[joint]
        cr = lay.cranks[joint]
        x0, y0 = lay.joint_pos[joint]
        psi = sy * (jp.extended_angle - jp.range)
        name = body_name(joint, side)
        w(f'{indent}<body name="{name}" pos="{_vec(x0, sy * y0, 0)}" quat="{_quat_z(psi)}">')
        ind = indent + "  "
        w(f'{ind}<joint name="{joint}_{side}" type="hinge" axis="0 0 {_f(sy)}" range="0 {_f(jp.range)}" '
          f'limited="false" damping="{_f(jp.damping)}" frictionloss="{_f(jp.friction)}"/>')
        L = legs.segment_length(joint)
        m = lay.segment_mass[joint]
        Ix, Iy, Iz = lay.segment_inertia[joint]
        w(f'{ind}<inertial pos="{_vec(0.5 * L, 0, 0)}" quat="1 0 0 0" mass="{_f(m)}" '
          f'diaginertia="{_vec(Ix, Iy, Iz)}"/>')
        # crank pins on this segment (at theta = 0 in this frame), anchors of the next joint
        for group, pin in (("drive", cr.drive_pin), ("recover", cr.recovery_pin)):
            w(f'{ind}<site name="{joint}_{side}_{group}_pin" pos="{_vec(pin[0], sy * pin[1], MUSCLE_Z[group])}" '
              'size="0.006" rgba="0.9 0.9 0.9 1"/>')
            w(f'{ind}<geom type="capsule" fromto="0 0 {_f(MUSCLE_Z[group])} {_vec(pin[0], sy * pin[1], MUSCLE_Z[group])}" '
              'size="0.005" material="metal" contype="0" conaffinity="0" mass="0"/>')
        if joint != "ankle":
            w(f'{ind}<geom name="{name}_shell" type="capsule" fromto="0 0 0 {_f(L)} 0 0" size="{_f(R)}" '
              'material="shell" contype="0" conaffinity="0" mass="0"/>')
            nxt = JOINTS[JOINTS.index(joint) + 1]
            anc = lay.cranks[nxt].anchor
            for group in ("drive", "recover"):
                w(f'{ind}<site name="{nxt}_{side}_{group}_anchor" pos="{_vec(anc[0], sy * anc[1], MUSCLE_Z[group])}" '
                  'size="0.007" rgba="0.2 0.2 0.2 1"/>')
        else:
            phi = palm_fan_angle(robot.palms.open_area, L)
            w(f'{ind}<geom name="{name}_spoke" type="capsule" fromto="0 0 0 {_f(L)} 0 0" size="0.006" '
              'material="metal" contype="0" conaffinity="0" mass="0"/>')
            t = 0.5 * legs.palm_thickness
            for k, hh in enumerate(palm_visual_heights(phi, L)):
                xk = L * (k + 0.5) / PALM_STRIPS
                w(f'{ind}<geom name="{name}_membrane{k}" type="box" size="{_vec(0.5 * L / PALM_STRIPS, t, hh)}" '
                  f'pos="{_vec(xk, 0, 0)}" material="membrane" contype="0" conaffinity="0" mass="0"/>')
        opened.append(indent)
        indent = ind
    for ind in reversed(opened):
        w(f"{ind}</body>")
    # hip anchors live on the hull: written after the leg (same body)
    anc = lay.cranks["hip"].anchor
    for group in ("drive", "recover"):
        w(f'      <site name="hip_{side}_{group}_anchor" pos="{_vec(anc[0], sy * anc[1], MUSCLE_Z[group])}" '
          'size="0.007" rgba="0.2 0.2 0.2 1"/>')


def _tendon(w, name, joint, side, group, width, rgba, extra="") -> None:
    w(f'    <spatial name="{name}" width="{_f(width)}" rgba="{rgba}"{extra}>')
    w(f'      <site site="{joint}_{side}_{group}_anchor"/>')
    w(f'      <site site="{joint}_{side}_{group}_pin"/>')
    w('    </spatial>')


def write_mjcf(rs, path) -> Path:
    """Write the MJCF of a robot scenario to ``path`` (atomically) and return the path."""
    from frogsim._files import atomic_write
    text = build_mjcf(rs)
    path = Path(path)

    def write(tmp):
        with open(tmp, "w") as fh:
            fh.write(text)
    atomic_write(path, write)
    return path
