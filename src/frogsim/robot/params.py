"""Parameters of the robot as a moving body: Table 1 of the paper, the mounting geometry, the water.

These dataclasses read the robot sections of a parameter set (``[muscle_force]``, ``[body]``,
``[legs]``, ``[joints.hip|knee|ankle]``, ``[palms]``, ``[water]``, ``[hydro]``; see
``params/fan2017.toml``) into SI floats, with the same validation as the pneumatic sections
(:mod:`frogsim.scenario.fields`): every value has a unit and bounds, unknown keys are refused.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from frogsim.scenario.fields import (build, choice, integer, parse_field, quantity,
                                         unknown_key_error, unwrap)
from frogsim.errors import MISSING, ScenarioError

JOINTS = ("hip", "knee", "ankle")          # proximal to distal: body-thigh, thigh-crus, crus-palm
SIDES = ("left", "right")


@dataclass(frozen=True)
class MuscleForceLaw:
    """Force law of the DMSP-20 muscles (:mod:`frogsim.physics.muscle_force`), with its optional
    hysteresis (off: ``hysteresis = "none"``, the default; :mod:`frogsim.physics.hysteresis`)."""
    model: str = choice(("dmsp20", "ideal"), doc="ideal: Chou-Hannaford only")
    force_scale: float = quantity("force", ge=0.0, display="N")
    strain_scale: float = quantity("dimensionless", gt=0.0, le=1.0, display="%")
    stiffness: float = quantity("force", ge=0.0, display="N", doc="per unit contraction")
    stretch_stiffness: float = quantity("force", ge=0.0, display="N", doc="per unit strain")
    stretch_quadratic: float = quantity("force", ge=0.0, display="N", doc="per unit strain squared")
    hysteresis: str = choice(("none", "maxwell-slip"), default="none",
                             doc="maxwell-slip: slip elements on the contraction (physics/hysteresis.py)")
    slip_elements: int = integer(ge=1, le=32, default=4, doc="number of Maxwell-slip elements")
    slip_per_pressure: float = quantity("area", ge=0.0, le=1e-2, display="N/bar", default=0.0,
                                        doc="half the loop's height per gauge pressure")
    slip_strain: float = quantity("dimensionless", gt=0.0, le=0.5, display="%", default=0.01,
                                  doc="the widest element's slide-free contraction")


@dataclass(frozen=True)
class Body:
    """The hull (Table 1) and its ballast."""
    length: float = quantity("length", gt=0.0, le=10.0, display="m")
    width: float = quantity("length", gt=0.0, le=10.0, display="m")
    total_mass: float = quantity("mass", gt=0.0, display="kg", doc="robot without ballast")
    displacement: float = quantity("volume", gt=0.0, display="L")
    ballast: str = field(metadata={})      # "neutral" or a mass such as "5 kg"
    ballast_depth: float = quantity("length", ge=0.0, display="mm",
                                    doc="ballast below the body centre")

    def ballast_mass(self, water_density: float) -> float:
        """Ballast [kg]: the given mass, or for "neutral" the mass that makes the robot weigh
        exactly the water it displaces, rho_w V_d - m (Archimedes)."""
        if self.ballast == "neutral":
            return water_density * self.displacement - self.total_mass
        return parse_field(self.ballast, BALLAST_META, "body.ballast")


BALLAST_META = dict(kind="mass", ge=0.0, display="kg")


@dataclass(frozen=True)
class Legs:
    """The two hind legs: where they attach, segment lengths (Table 1), shells and masses."""
    hip_x: float = quantity("length", ge=-5.0, le=5.0, display="mm", doc="forward of the body centre")
    hip_y: float = quantity("length", gt=0.0, le=5.0, display="mm", doc="left hip; the right is mirrored")
    thigh_length: float = quantity("length", gt=0.0, le=5.0, display="m")
    crus_length: float = quantity("length", gt=0.0, le=5.0, display="m")
    palm_length: float = quantity("length", gt=0.0, le=5.0, display="m")
    segment_radius: float = quantity("length", gt=0.0, le=1.0, display="mm")
    thigh_mass: float = quantity("mass", gt=0.0, display="kg")
    crus_mass: float = quantity("mass", gt=0.0, display="kg")
    palm_mass: float = quantity("mass", gt=0.0, display="kg")
    palm_thickness: float = quantity("length", gt=0.0, le=0.1, display="mm")

    def segment_length(self, joint: str) -> float:
        """Length of the segment a joint moves (hip: thigh, knee: crus, ankle: palm) [m]."""
        return {"hip": self.thigh_length, "knee": self.crus_length, "ankle": self.palm_length}[joint]

    def segment_mass(self, joint: str) -> float:
        return {"hip": self.thigh_mass, "knee": self.crus_mass, "ankle": self.palm_mass}[joint]


@dataclass(frozen=True)
class Joint:
    """One joint: its muscles' type and crank, its range of motion and end stops, friction and
    recovery spring.

    The joint angle is 0 at the flexed stop (driving muscle at its rest length) and grows with
    extension up to ``range``; ``extended_angle`` is the segment's angle to its parent there. At
    both ends an elastomer pad stops the joint: ``stop_stiffness`` and ``stop_damping`` about the
    joint axis (:mod:`frogsim.physics.stop`).
    """
    muscle_type: str = field(metadata={})
    range: float = quantity("angle", gt=0.0, lt=math.pi, display="deg")
    extended_angle: float = quantity("angle", ge=-math.pi, le=math.pi, display="deg")
    friction: float = quantity("torque", ge=0.0, display="N*m")
    damping: float = quantity("rotational_damping", ge=0.0, display="N*m*s")
    spring_stiffness: float = quantity("stiffness", ge=0.0, display="N/m")
    spring_preload: float = quantity("force", ge=0.0, display="N")
    stop_stiffness: float = quantity("rotational_stiffness", gt=0.0, display="N*m/rad",
                                     doc="end stops' pads about the joint axis")
    stop_damping: float = quantity("rotational_damping", ge=0.0, display="N*m*s",
                                   doc="end stops' pads, per radian")


@dataclass(frozen=True)
class Palms:
    """The palms (paper Fig. 5): a membrane fanned by spokes that a steering motor opens and folds."""
    open_area: float = quantity("area", gt=0.0, display="m^2")
    folded_area: float = quantity("area", gt=0.0, display="m^2")
    motor_travel_time: float = quantity("time", gt=0.0, le=10.0, display="s")


@dataclass(frozen=True)
class Water:
    """The water the robot swims in."""
    density: float = quantity("density", gt=0.0, display="kg/m^3")
    gravity: float = quantity("acceleration", ge=0.0, display="m/s^2")


@dataclass(frozen=True)
class Hydro:
    """Coefficients of the quasi-steady drag (:mod:`frogsim.physics.hydro`)."""
    plate_normal_drag: float = quantity("dimensionless", ge=0.0, le=5.0)
    segment_crossflow_drag: float = quantity("dimensionless", ge=0.0, le=5.0)
    skin_friction: float = quantity("dimensionless", ge=0.0, le=0.1)
    body_axial_drag: float = quantity("dimensionless", ge=0.0, le=5.0)
    body_lateral_drag: float = quantity("dimensionless", ge=0.0, le=5.0)
    body_vertical_drag: float = quantity("dimensionless", ge=0.0, le=5.0)
    strips: int = integer(ge=1, le=64)


@dataclass(frozen=True)
class RobotParams:
    """All robot sections of a parameter set, validated."""
    muscle_force: MuscleForceLaw
    body: Body
    legs: Legs
    joints: dict
    palms: Palms
    water: Water
    hydro: Hydro


ROBOT_SECTIONS = ("muscle_force", "body", "legs", "joints", "palms", "water", "hydro")


def robot_params_from_raw(raw: dict, muscle_types: dict) -> RobotParams:
    """Validate the robot sections of a merged scenario dict (see :mod:`frogsim.scenario.load`)."""
    for key in ROBOT_SECTIONS:
        if key not in raw:
            raise ScenarioError(key, MISSING, "required robot section is missing (parameter set "
                                              "without the robot? see params/fan2017.toml)")
    joints_raw = raw["joints"]
    if not isinstance(joints_raw, dict):
        raise ScenarioError("joints", joints_raw, "expected [joints.hip], [joints.knee], [joints.ankle]")
    for name in joints_raw:
        if name not in JOINTS:
            raise unknown_key_error("joints", name, JOINTS)
    joints = {}
    for name in JOINTS:
        if name not in joints_raw:
            raise ScenarioError(f"joints.{name}", MISSING, "required joint section is missing")
        j = build(Joint, joints_raw[name], f"joints.{name}")
        if j.muscle_type not in muscle_types:
            raise ScenarioError(f"joints.{name}.muscle_type", j.muscle_type,
                                f"must name a muscle type ({', '.join(sorted(muscle_types))})")
        joints[name] = j
    body = build(Body, raw["body"], "body")
    if body.ballast != "neutral":
        parse_field(body.ballast, BALLAST_META, "body.ballast")
    palms = build(Palms, raw["palms"], "palms")
    if palms.folded_area >= palms.open_area:
        raise ScenarioError("palms.folded_area", unwrap(raw["palms"].get("folded_area")),
                            f"must be below palms.open_area ({palms.open_area:g} m^2)")
    water = build(Water, raw["water"], "water")
    if body.ballast_mass(water.density) < 0.0:
        raise ScenarioError("body.total_mass", unwrap(raw["body"].get("total_mass")),
                            "is more than the water the body displaces: the robot cannot be made "
                            "neutrally buoyant by ballast")
    return RobotParams(muscle_force=build(MuscleForceLaw, raw["muscle_force"], "muscle_force"),
                       body=body, legs=build(Legs, raw["legs"], "legs"), joints=joints,
                       palms=palms, water=water, hydro=build(Hydro, raw["hydro"], "hydro"))


def parameter_set_law(scenario, purpose: str = "muscle tensions need a force law") -> MuscleForceLaw:
    """The ``[muscle_force]`` law of a pneumatic scenario: its parameter set's, with the scenario's
    own ``[muscle_force]`` settings laid over it (kept in ``scenario.raw``, variants included), or a
    ScenarioError saying there is none and what needed it (``purpose``)."""
    from frogsim.errors import UNKNOWN
    from frogsim.scenario.load import load_parameter_set
    raw = scenario.raw if "muscle_force" in scenario.raw else load_parameter_set(scenario.parameters,
                                                                                 scenario.base_dir)
    if "muscle_force" not in raw:
        raise ScenarioError(f"parameters {scenario.parameters!r}", UNKNOWN,
                            f"has no [muscle_force] table: {purpose}")
    return build(MuscleForceLaw, raw["muscle_force"], "muscle_force")
