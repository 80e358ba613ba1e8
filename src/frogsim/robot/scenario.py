"""Robot scenarios: the robot of a parameter set, a gait, and where it runs (water or air, free or
fixed), validated into a :class:`RobotScenario`.

A robot scenario file holds the run's own settings and may override any parameter-set value like
any scenario (:mod:`frogsim.scenario.load`); instead of ``[muscles]`` it has ``[robot]`` and
``[gait]``, from which the muscles (two per joint and leg, or one and a spring) and their valve
programs are made::

    name = "swim"
    parameters = "fan2017"
    output_interval = "10 ms"
    [robot]
    environment = "water"     # "water" or "air"
    base = "free"             # "free": it swims; "fixed": the body is held on a base
    planar = true             # body held to the horizontal plane (x, y, yaw)
    recovery = "muscle"       # "muscle" (antagonistic pairs) or "spring" (paper Sec. 4.1 variant)
    timestep = "1 ms"         # MuJoCo step; the pneumatics adapt their own steps inside it
    [gait]                    # see frogsim.control.gait
    [controllers.hip]         # optional closed-loop control (docs/control.md), e.g.
    kind = "joint-angle"      # the hip_left / hip_left_recovery pair tracking an angle
    joint = "hip_left"
    setpoint = "20 deg"

Muscles under a closed-loop controller take no gait commands; a joint-angle controller takes
both muscles of its joint (:func:`joint_pairs`) and its setpoint must stay in the joint's range.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from frogsim.scenario.fields import build, choice, flag, quantity, shown, unwrap
from frogsim.scenario.core import Scenario
from frogsim.scenario.motion import whole_steps
from frogsim.scenario.schema import Motion, Muscle, Program
from frogsim.control.gait import Gait, muscle_programs
from frogsim.scenario.kinds import KINDS
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.load import merged_raw, scenario_from_raw
from frogsim.robot.geometry import Layout, layout
from frogsim.robot.params import JOINTS, SIDES, RobotParams, robot_params_from_raw


@dataclass(frozen=True)
class RobotOptions:
    """Where and how the robot runs (the scenario's ``[robot]`` table)."""
    environment: str = choice(("water", "air"), default="water")
    base: str = choice(("free", "fixed"), default="free")
    planar: bool = flag(default=True)
    recovery: str = choice(("muscle", "spring"), default="muscle")
    timestep: float = quantity("time", gt=0.0, le=0.01, display="ms", default=0.001)


@dataclass(frozen=True)
class RobotScenario:
    """Everything about one robot run: pneumatics (a validated Scenario), robot, gait, options."""
    name: str
    pneumatic: Scenario
    robot: RobotParams
    options: RobotOptions
    gait: Gait
    layout: Layout
    muscles: dict              # muscle name -> (joint, side, group "drive"/"recover")
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def duration(self) -> float:
        return self.gait.duration

    @property
    def medium_density(self) -> float:
        """Density of the water, or of the air at the ambient state p/(R T) [kg/m^3]."""
        if self.options.environment == "water":
            return self.robot.water.density
        a = self.pneumatic.air
        return a.atmospheric_pressure_abs / (a.gas_constant * a.ambient_temperature)


def muscle_names(recovery: str) -> dict:
    """Muscle name -> (joint, side, group): "hip_left" drives, "hip_left_recovery" recovers."""
    out = {}
    for side in SIDES:
        for j in JOINTS:
            out[f"{j}_{side}"] = (j, side, "drive")
    if recovery == "muscle":
        for side in SIDES:
            for j in JOINTS:
                out[f"{j}_{side}_recovery"] = (j, side, "recover")
    return out


def joint_pairs(names: dict) -> dict:
    """Joint name ("hip_left") -> (extensor, flexor) muscle names, in the coupled engine's joint
    order (left hip, knee, ankle, then right); the flexor is None with spring recovery."""
    out = {}
    for side in SIDES:
        for j in JOINTS:
            ext = f"{j}_{side}"
            flex = f"{j}_{side}_recovery"
            out[ext] = (ext, flex if flex in names else None)
    return out


def controlled_muscles(raw_controllers, pairs: dict) -> set:
    """The muscles a scenario's closed-loop ``[controllers]`` take from the gait (read before the
    controllers are validated; a misnamed joint or muscle is refused afterwards)."""
    out = set()
    if not isinstance(raw_controllers, dict):
        return out
    for c in raw_controllers.values():
        if not isinstance(c, dict):
            continue
        cls = KINDS.get(unwrap(c.get("kind")))
        if cls is None or not cls.closed_loop:
            continue
        named = unwrap(c.get(cls.NAMED))
        if cls.NAMED == "joint":
            out.update(m for m in pairs.get(named, ()) if m)
        elif isinstance(named, str):
            out.add(named)
    return out


def check_joint_setpoints(sc: Scenario, robot: RobotParams) -> None:
    """A joint-angle setpoint must stay inside its joint's range (0 at the flexed stop to the
    joint's range at full extension)."""
    for cname, c in sc.controllers.items():
        if c.NAMED != "joint":
            continue
        lo, hi = c.setpoint.bounds()
        top = robot.joints[c.joint.split("_")[0]].range
        if lo < 0.0 or hi > top:
            bad = lo if lo < 0.0 else hi
            raise ScenarioError(f"controllers.{cname}.setpoint", f"{math.degrees(bad):.4g} deg "
                                f"({'lowest' if lo < 0.0 else 'highest'} value)",
                                f"must lie in the joint's range, 0 to {math.degrees(top):.4g} deg "
                                f"(joints.{c.joint.split('_')[0]}.range)")


#: a joint-angle gain may span the pressure range for no less than this fraction of the joint's range
#: (see :func:`check_joint_gains`)
GAIN_RANGE_FRACTION = 1e-3


def joint_gain_limits(sc: Scenario, robot: RobotParams, joint: str) -> dict:
    """The largest Kp [Pa/rad], Kd [Pa s/rad] and Ki [Pa/(rad s)] of a joint-angle controller on
    ``joint`` ("hip_left"), by setting name.

    The targets p0 ± Δp/2 stay within [atmosphere, source] only while |Δp| is at most the source's
    gauge pressure P (at p0 = P/2; less elsewhere). With e* = GAIN_RANGE_FRACTION times the
    joint's range R (0.04 deg at the hip) and T the controller period, each term alone reaches P
    no sooner than at an angle error of e* (Kp e* <= P), a rate of e* per sample (Kd e*/T <= P)
    or an error of e* integrated over one sample (Ki e* T <= P). A larger gain makes its term a
    relay on errors the joint crosses within a MuJoCo step at about 1 rad/s: a PID no longer."""
    p = _top_pressure(sc)
    e = GAIN_RANGE_FRACTION * robot.joints[joint.split("_")[0]].range
    dt = 1.0 / sc.controller.rate
    return {"proportional_gain": p / e, "derivative_gain": p * dt / e, "integral_gain": p / (e * dt)}


def _top_pressure(sc: Scenario) -> float:
    """The highest source pressure [Pa gauge]: the start's, or the pump's upper switch when it runs."""
    p = sc.source.initial_pressure_gauge
    if sc.pump.enabled and sc.pump.displacement > 0:
        p = max(p, sc.pump.off_above_gauge)
    return p


def check_joint_gains(sc: Scenario, robot: RobotParams) -> None:
    """Each gain of a joint-angle controller within :func:`joint_gain_limits`, refused in one line
    with the allowed range and why."""
    for cname, c in sc.controllers.items():
        if c.NAMED != "joint" or _top_pressure(sc) <= 0.0:
            continue
        limits = joint_gain_limits(sc, robot, c.joint)
        for key, top in limits.items():
            x = getattr(c, key)
            if x > top:
                meta = c.settings()[key].metadata
                top_shown = shown(top, meta)
                rng = math.degrees(robot.joints[c.joint.split("_")[0]].range)
                per = {"proportional_gain": "an angle error of",
                       "derivative_gain": "a change per controller period of",
                       "integral_gain": "an error held for one controller period of"}[key]
                raise ScenarioError(f"controllers.{cname}.{key}", shown(x, meta),
                                    f"allowed: 0 to {top_shown}: a larger gain alone spans the pressure range "
                                    f"[atmosphere, source] ({_top_pressure(sc) / 1e5:g} bar) for {per} "
                                    f"{GAIN_RANGE_FRACTION * 100:g} % of the joint's range ({rng:.4g} deg; controller "
                                    f"at {sc.controller.rate:g} Hz): a relay, not a PID")


def check_controller_rate(rate: float, timestep: float) -> None:
    """The controller's period must be a whole number of MuJoCo steps: the coupled engine reads the
    joints and applies the gait's commands at its steps, so a sample between two steps would
    read an angle as old as a step and a rate of 1/timestep is the fastest the robot can mean."""
    if whole_steps(1.0 / rate, timestep) is None:
        top = 1.0 / timestep
        raise ScenarioError("controller.rate", f"{rate:g} Hz",
                            f"its period {1e3 / rate:g} ms must be a whole number of robot.timestep steps "
                            f"({timestep * 1e3:g} ms): allowed {top:g} Hz / n ({top:g} Hz, {top / 2:g} Hz, "
                            f"{top / 3:.6g} Hz, ...)")


def check_step_grid(output_interval: float, period: float, timestep: float) -> None:
    """The coupled engine records whole MuJoCo steps (t_k = k robot.timestep): the output interval
    and the gait's period (so the run's duration) must be whole numbers of steps, or a recorded
    row would not be at the time its name says."""
    for path, value in (("output_interval", output_interval), ("gait.period", period)):
        if whole_steps(value, timestep) is None:
            raise ScenarioError(path, f"{value * 1e3:g} ms", f"must be a whole number of robot.timestep "
                                                             f"steps ({timestep * 1e3:g} ms): the robot is "
                                                             f"recorded at its MuJoCo steps")


def load_robot_scenario(source, cycles: int | None = None, output_interval: float | None = None) -> RobotScenario:
    """Load and validate a robot scenario (a TOML path, a shipped name such as "swim", or a dict).

    ``cycles`` overrides ``gait.cycles``, ``output_interval`` [s] the scenario's output interval
    (checked as if written in the file). Raises ScenarioError naming field, value and what is
    allowed; nothing is run.
    """
    raw, base_dir = merged_raw(source)
    if output_interval is not None:
        raw["output_interval"] = f"{output_interval!r} s"
    if raw.get("muscles"):
        raise ScenarioError("muscles", "(a table)", "a robot scenario makes its muscles from "
                                                    "[joints] and [gait]: remove [muscles]")
    if "gait" not in raw:
        raise ScenarioError("gait", MISSING, "a robot scenario needs a [gait] table "
                                             "(see frogsim.control.gait)")
    options = build(RobotOptions, raw.get("robot", {}), "robot")
    gait = Gait.from_raw(raw["gait"], JOINTS, cycles)
    types = raw.get("muscle_types")
    robot = robot_params_from_raw(raw, types if isinstance(types, dict) else {})
    names = muscle_names(options.recovery)
    pairs = joint_pairs(names)
    programs = muscle_programs(gait, {n: (j, g) for n, (j, _, g) in names.items()})
    free = controlled_muscles(raw.get("controllers"), pairs)
    muscles = {name: Muscle(type=robot.joints[joint].muscle_type,
                            program=Program() if name in free else programs[name],
                            motion=Motion("constant"))
               for name, (joint, _, _) in names.items()}
    pneumatic = scenario_from_raw(raw, base_dir, duration=gait.duration, muscles=muscles, joints=pairs)
    check_joint_setpoints(pneumatic, robot)
    check_joint_gains(pneumatic, robot)
    check_controller_rate(pneumatic.controller.rate, options.timestep)
    check_step_grid(pneumatic.output_interval, gait.period, options.timestep)
    lay = layout(robot, pneumatic.muscle_types)
    return RobotScenario(name=pneumatic.name, pneumatic=pneumatic, robot=robot, options=options,
                         gait=gait, layout=lay, muscles=names, raw=raw)
